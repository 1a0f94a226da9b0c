"""Embedded synthetic scenes, loaders for the real data sets, and all of them by name."""

from collections.abc import Callable

from ehm.core.sensor.scan import Scan
from ehm.errors import InputError
from ehm.eval.datasets.depth_camera import dense_room
from ehm.eval.datasets.outdoor import hillside
from ehm.eval.datasets.power_lines import power_lines
from ehm.eval.datasets.real import REAL_DATASETS, DataMissingError
from ehm.eval.datasets.scene import Scene
from ehm.eval.datasets.simulated import (
    SimulatedDataset,
    floor_plan_2d,
    outdoor_lidar,
    street,
    virtual_room,
    warehouse,
)

DATASETS: dict[str, Callable[[], list[Scan]]] = {
    "virtual_room": lambda: virtual_room().scans,
    "warehouse": lambda: warehouse().scans,
    "street": lambda: street().scans,
    "dense_room": lambda: dense_room().scans,
    "dense_room_noisy": lambda: dense_room(noise_std=0.01).scans,
    **REAL_DATASETS,
}
"""The evaluation's data sets by name, each a loader of its scans in order."""


def load_dataset(name: str) -> list[Scan]:
    """The scans of data set `name` (see DATASETS). ValueError for an unknown name;
    DataMissingError when a real data set's files are absent."""
    if name not in DATASETS:
        raise InputError(f"unknown data set {name!r}; known: {', '.join(DATASETS)}")
    return DATASETS[name]()


__all__ = [
    "DATASETS",
    "DataMissingError",
    "Scene",
    "SimulatedDataset",
    "dense_room",
    "floor_plan_2d",
    "hillside",
    "load_dataset",
    "outdoor_lidar",
    "power_lines",
    "street",
    "virtual_room",
    "warehouse",
]
