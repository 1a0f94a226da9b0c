"""Opening a map of either kind: a HilbertMap's file or a TiledMap's directory."""

from __future__ import annotations

from os import PathLike
from pathlib import Path

from ehm.hilbert_map import HilbertMap
from ehm.tiles.tiled_map import TiledMap


def load(path: str | PathLike[str]) -> HilbertMap | TiledMap:
    """The map at `path`: a map file written by HilbertMap.save, which answers and goes on
    learning exactly as the saved map would, or a map directory written by a TiledMap, opened
    lazily (a query reads only the tiles it touches). FileReadError (MapFileError for a bad
    map file) names what is wrong."""
    if Path(path).is_dir():
        return TiledMap.open(path)
    return HilbertMap.load(path)
