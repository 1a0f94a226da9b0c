"""The map directory of a tiled map: one .ehm map file per tile and an index.

    city.ehm/
        index.json          format, tiling, settings, scans, sensor path, and per tile its
                            key, version, scans, clusters, file size and cluster extent
        tiles/0_-1_0.ehm    tile (0, -1, 0): an ordinary map file (ehm.io.map_file)

Every file is written atomically (ehm.io.files.write_atomically): tiles one by one as they
are learned, the index last, so a reader sees the previous index and the tiles it names until
the new one is complete. A tile's version counts the times it was written.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from os import PathLike
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ehm.core.model.kernels import kernel_reach
from ehm.errors import FileReadError, OutputError
from ehm.io.files import read_text, write_atomically
from ehm.io.output_paths import check_output_map_directory

if TYPE_CHECKING:
    from ehm.hilbert_map import HilbertMap

INDEX_NAME = "index.json"
TILES_FOLDER = "tiles"
INDEX_FORMAT = "ehm tiled map"
INDEX_VERSION = 1

TileKey = tuple[int, ...]


class TileIndexError(FileReadError):
    """A map directory whose index is missing, foreign, too new or inconsistent."""


@dataclass(frozen=True)
class TileRecord:
    """What the index says of one tile: version (times written), n_scans (scans that crossed
    it), n_clusters, n_bytes (its file) and extent ((2, d) metres, the box holding every
    kernel's support, as nested lists; empty for a tile without clusters)."""

    version: int
    n_scans: int
    n_clusters: int
    n_bytes: int
    extent: list

    @classmethod
    def of_map(cls, tile_map: HilbertMap, version: int, n_bytes: int) -> TileRecord:
        """The record of a tile's map, without learning its waiting scans: its extent is the
        box of its kernels' support within its learn box."""
        clusters = tile_map.clusters_
        n_clusters = 0 if clusters is None else len(clusters)
        extent: list = []
        if n_clusters:
            reach = kernel_reach(clusters.transforms, clusters.planar_kernel)[:, None]
            box = np.asarray(tile_map.config.learn_box).reshape(2, -1)
            means = clusters.means + (
                tile_map.local_origin_ if tile_map.local_origin_ is not None else 0.0
            )
            low = np.maximum((means - reach).min(axis=0), box[0])
            high = np.minimum((means + reach).max(axis=0), box[1])
            extent = [low.tolist(), high.tolist()]
        return cls(version, tile_map.n_scans_, n_clusters, n_bytes, extent)


@dataclass
class TileIndex:
    """The index of a map directory: tile_size and overlap, metres; dim; config, the
    settings every tile shares (a MapConfig's dict); n_scans; sensor_path, one origin per
    scan; tiles, a TileRecord per tile key."""

    tile_size: float
    overlap: float
    dim: int
    config: dict
    n_scans: int
    sensor_path: list
    tiles: dict[TileKey, TileRecord]

    def to_json(self) -> str:
        fields = asdict(self)
        fields["tiles"] = [
            {"key": list(key), **asdict(record)} for key, record in sorted(self.tiles.items())
        ]
        return json.dumps({"format": INDEX_FORMAT, "version": INDEX_VERSION, **fields})

    @classmethod
    def of_json(cls, text: str, path: str | PathLike[str]) -> TileIndex:
        try:
            fields = json.loads(text)
        except ValueError as error:
            raise TileIndexError(path, f"not JSON ({error})") from None
        if not isinstance(fields, dict) or fields.get("format") != INDEX_FORMAT:
            raise TileIndexError(path, "not the index of a tiled ehm map")
        if not isinstance(fields.get("version"), int) or fields["version"] > INDEX_VERSION:
            raise TileIndexError(
                path, f"index version {fields.get('version')!r} is newer than this ehm reads"
            )
        try:
            tiles = {}
            for entry in fields["tiles"]:
                key = tuple(int(v) for v in entry.pop("key"))
                tiles[key] = TileRecord(**entry)
            return cls(
                float(fields["tile_size"]),
                float(fields["overlap"]),
                int(fields["dim"]),
                dict(fields["config"]),
                int(fields["n_scans"]),
                list(fields["sensor_path"]),
                tiles,
            )
        except (KeyError, TypeError, ValueError) as error:
            raise TileIndexError(path, f"inconsistent index ({error!r})") from None


def tile_name(key: TileKey) -> str:
    """The file name of tile `key`, for example '3_-1_0.ehm'."""
    return "_".join(str(k) for k in key) + ".ehm"


class TileStore:
    """A map directory on disk: its index and tile files (see the module's docstring)."""

    def __init__(self, directory: str | PathLike[str]) -> None:
        self.directory = Path(directory)

    def __repr__(self) -> str:
        return f"TileStore({str(self.directory)!r})"

    @staticmethod
    def holds_map(path: str | PathLike[str]) -> bool:
        """Whether `path` is a folder with a tiled map's index."""
        return (Path(path) / INDEX_NAME).is_file()

    def tile_path(self, key: TileKey) -> Path:
        return self.directory / TILES_FOLDER / tile_name(key)

    def read_index(self) -> TileIndex:
        path = self.directory / INDEX_NAME
        if not path.is_file():
            raise TileIndexError(
                self.directory, f"a folder without {INDEX_NAME}: neither a map file nor a tiled map"
            )
        return TileIndex.of_json(read_text(path), path)

    def write_index(self, index: TileIndex) -> None:
        write_atomically(self.directory / INDEX_NAME, index.to_json().encode())

    def read_tile(self, key: TileKey) -> bytes:
        path = self.tile_path(key)
        try:
            return path.read_bytes()
        except OSError as error:
            raise FileReadError(path, f"tile {key} of the index cannot be read ({error})") from None

    def write_tile(self, key: TileKey, data: bytes) -> None:
        write_atomically(self.tile_path(key), data)

    def remove_tiles_except(self, keys: set[TileKey]) -> None:
        """Delete tile files that the index no longer names (left by a map written over)."""
        kept = {tile_name(key) for key in keys}
        for path in (self.directory / TILES_FOLDER).glob("*.ehm"):
            if path.name not in kept:
                path.unlink(missing_ok=True)

    def prepare(self) -> None:
        """Make the directory and its tiles folder where a tiled map may be written (see
        ehm.io.output_paths.check_output_map_directory: not a file, nor a folder of other files);
        OutputError otherwise and where making it fails."""
        check_output_map_directory(self.directory, force=True)
        try:
            (self.directory / TILES_FOLDER).mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise OutputError(f"cannot make the map directory {self.directory}: {error}") from None
