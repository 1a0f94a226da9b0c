"""Occupancy grids and meshes of a map (Sec. 3.5), computed from snapshots of it."""

from ehm.grid.occupancy_grid import GridUpdate, OccupancyGrid

__all__ = ["GridUpdate", "OccupancyGrid"]
