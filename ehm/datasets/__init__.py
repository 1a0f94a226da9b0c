"""Embedded synthetic scenes and loaders for the real data sets."""

from ehm.datasets.scene import Scene
from ehm.datasets.simulated import SimulatedDataset, floor_plan_2d, virtual_room, warehouse

__all__ = ["Scene", "SimulatedDataset", "floor_plan_2d", "virtual_room", "warehouse"]
