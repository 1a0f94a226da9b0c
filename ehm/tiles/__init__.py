"""Tiled maps for city-scale data: TiledMap, learned on Dask (ehm.tiles.build), stored as a
map directory (ehm.tiles.store) and read lazily."""

from ehm.tiles.sources import ScanList, ScanSource
from ehm.tiles.tiled_map import TiledMap

__all__ = ["ScanList", "ScanSource", "TiledMap"]
