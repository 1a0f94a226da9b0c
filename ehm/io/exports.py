"""A map's grid in the formats robotics tools read: OctoMap trees (.ot, .bt), ROS map_server
images (.pgm with its .yaml, from a navigation grid, ehm.grid.navigation) and point clouds of
the occupied voxels (.ply, .pcd).

Voxels that no kernel reaches (log-odds exactly 0 before the intercept) are unknown: left out
of OctoMap trees, never occupied.

    write_octomap(hilbert_map.grid_blocks(resolution=0.1), "map.bt")
"""

from __future__ import annotations

from collections.abc import Iterable
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.errors import InputError, OutputError
from ehm.grid.bounds import DEFAULT_MAX_BYTES
from ehm.grid.navigation import FREE, OCCUPIED, NavigationGrid
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.io.octomap_bindings import octomap_module

OCTOMAP_SUFFIXES = (".ot", ".bt")
# What an OctoMap tree takes a known voxel, leaves and inner nodes (45 measured on a LiDAR
# sweep's tree of 14 million voxels).
OCTOMAP_BYTES_PER_VOXEL = 48
# OctoMap keys hold 16 bits per axis, centred on the origin.
OCTOMAP_KEY_HALF = 2**15
# map_server's reading of a pixel p: occupancy (255 - p) / 255, above occupied_thresh occupied,
# below free_thresh free, between them unknown. map_saver's thresholds and unknown grey.
MAP_SERVER_OCCUPIED = 0.65
MAP_SERVER_FREE = 0.196
MAP_SERVER_OCCUPIED_PIXEL, MAP_SERVER_FREE_PIXEL, MAP_SERVER_UNKNOWN_PIXEL = 0, 254, 205


def write_octomap(
    grids: OccupancyGrid | Iterable[OccupancyGrid],
    path: str | PathLike[str],
    max_bytes: int = DEFAULT_MAX_BYTES,
) -> int:
    """Write a 3D grid, or the blocks of one (HilbertMap.grid_blocks), on multiples of the
    resolution (ehm.grid.bounds.aligned_bounds), as an OctoMap OcTree: `.ot` keeps each
    known voxel's occupancy as log-odds, `.bt` its maximum likelihood (occupied above 0.5,
    else free), pruned. Written by OctoMap itself (octomap-python), so octovis and
    octomap_server open it. Returns the known voxels. InputError, as soon as it is known,
    when the tree would take more than `max_bytes` (OCTOMAP_BYTES_PER_VOXEL a known voxel)."""
    path = Path(path)
    if path.suffix not in OCTOMAP_SUFFIXES:
        raise OutputError(f"{path}: OctoMap files end in .ot or .bt")
    grids = [grids] if isinstance(grids, OccupancyGrid) else grids
    tree, known = octree_of_grids(grids, max_bytes)
    written = (
        tree.writeBinary(str(path).encode())
        if path.suffix == ".bt"
        else tree.write(str(path).encode())
    )
    if not written:
        raise OutputError(f"{path}: OctoMap could not write it")
    return known


def octree_of_grids(grids: Iterable[OccupancyGrid], max_bytes: int = DEFAULT_MAX_BYTES):
    """The octomap.OcTree holding the known voxels of 3D grids of one resolution that do not
    overlap, at their log-odds (clamped by OctoMap at +-13.8, probabilities 1e-6 from 0 and
    1), and how many voxels it holds; InputError once they pass `max_bytes` in the tree."""
    tree, known = None, 0
    for grid in grids:
        _check_octomap_grid(grid)
        if tree is None:
            tree = octomap_module().OcTree(grid.resolution)
            tree.setClampingThresMin(1e-6)
            tree.setClampingThresMax(1.0 - 1e-6)
        elif tree.getResolution() != grid.resolution:
            raise InputError("one OctoMap tree holds voxels of one resolution")
        voxels = np.argwhere(grid.scores != 0.0)
        if (known + len(voxels)) * OCTOMAP_BYTES_PER_VOXEL > max_bytes:
            raise InputError(
                f"the OctoMap tree passes {known + len(voxels)} known voxels of "
                f"{grid.resolution:g} m, more than the limit of {max_bytes / 2**30:.2f} GiB "
                "holds: coarsen the resolution, shrink the bounds or raise the limit "
                "(max_bytes; --max-gib)"
            )
        centres = grid.origin + (voxels + 0.5) * grid.resolution
        log_odds = grid.scale * (grid.scores[tuple(voxels.T)] + grid.intercept)
        for centre, value in zip(centres, log_odds, strict=True):
            tree.updateNode(centre, float(value), True)
        known += len(voxels)
    if tree is None:
        raise InputError("no voxels to write: the map has no kernels within the bounds")
    tree.updateInnerOccupancy()
    return tree, known


def _check_octomap_grid(grid: OccupancyGrid) -> None:
    """InputError for a grid whose voxels are not OctoMap's: 2D, off its voxel boundaries or
    beyond its keys' reach."""
    if grid.dim != 3:
        raise InputError("OctoMap trees are 3D; a 2D map exports as a map_server image (.pgm)")
    cells = grid.origin / grid.resolution
    if not np.allclose(cells, np.round(cells), atol=1e-6):
        raise InputError(
            f"grid origin {grid.origin.tolist()} is not on OctoMap's voxel boundaries, "
            f"multiples of {grid.resolution} m (see ehm.grid.bounds.aligned_bounds)"
        )
    reach = OCTOMAP_KEY_HALF * grid.resolution
    low, high = grid.bounds
    if np.any(low < -reach) or np.any(high > reach):
        raise InputError(
            f"OctoMap's keys reach {reach:g} m from the origin at {grid.resolution} m; the grid "
            f"spans {low.tolist()} .. {high.tolist()}"
        )


def write_map_server(grid: NavigationGrid, path: str | PathLike[str]) -> Path:
    """Write a 2D navigation grid (ehm.grid.navigation) as a ROS map_server map: `path` (.pgm,
    8-bit, first row the top) with the pixels map_saver writes, 0 for occupied cells, 254 for
    free ones and 205 for unknown ones, and beside it a .yaml (image, resolution, origin,
    negate, thresholds; mode trinary), which nav2 and map_server read. Returns the .yaml's
    path."""
    path = Path(path)
    if not isinstance(grid, NavigationGrid):
        raise InputError(
            "map_server maps are written from a navigation grid, each cell occupied, free or "
            "unknown: ehm.grid.navigation.navigation_grid(map, bounds, resolution)"
        )
    if grid.dim != 2:
        raise InputError(
            "map_server maps are 2D: project a 3D map's height band first "
            "(ehm.grid.navigation.projected_navigation_grid)"
        )
    if path.suffix != ".pgm":
        raise OutputError(f"{path}: map_server images end in .pgm")
    pixels = np.full(grid.shape, MAP_SERVER_UNKNOWN_PIXEL, dtype=np.uint8)
    pixels[grid.states == OCCUPIED] = MAP_SERVER_OCCUPIED_PIXEL
    pixels[grid.states == FREE] = MAP_SERVER_FREE_PIXEL
    image = pixels.T[::-1]  # rows from the top (largest y), columns along x
    height, width = image.shape
    with open(path, "wb") as stream:
        stream.write(f"P5\n# ehm occupancy map\n{width} {height}\n255\n".encode("ascii"))
        stream.write(np.ascontiguousarray(image).tobytes())
    yaml_path = path.with_suffix(".yaml")
    x0, y0 = (float(v) for v in grid.origin)
    yaml_path.write_text(
        f"image: {path.name}\n"
        f"resolution: {grid.resolution!r}\n"
        f"origin: [{x0!r}, {y0!r}, 0.0]\n"
        "negate: 0\n"
        f"occupied_thresh: {MAP_SERVER_OCCUPIED}\n"
        f"free_thresh: {MAP_SERVER_FREE}\n"
        "mode: trinary\n"
    )
    return yaml_path


def occupied_voxels(grid: OccupancyGrid, level: float = 0.5) -> np.ndarray:
    """(n, d) float64 centres, metres, of the voxels whose occupancy is above `level`."""
    if not 0.0 < level < 1.0:
        raise InputError(f"level must be a probability between 0 and 1, got {level}")
    occupied = np.argwhere((grid.probability > level) & (grid.scores != 0.0))
    return grid.origin + (occupied + 0.5) * grid.resolution


def write_point_cloud(points: np.ndarray, path: str | PathLike[str]) -> None:
    """Write (n, 3) points, metres, as binary little-endian PLY or binary PCD (float32 x y z),
    by the name's suffix; CloudCompare, Open3D and PCL read both."""
    path = Path(path)
    points = np.asarray(points, dtype="<f4")
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"points must have shape (n, 3), got {points.shape}")
    if path.suffix == ".ply":
        header = (
            f"ply\nformat binary_little_endian 1.0\ncomment written by ehm\n"
            f"element vertex {len(points)}\nproperty float x\nproperty float y\n"
            "property float z\nend_header\n"
        )
    elif path.suffix == ".pcd":
        header = (
            "# .PCD v0.7 - written by ehm\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
            f"COUNT 1 1 1\nWIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
            f"POINTS {len(points)}\nDATA binary\n"
        )
    else:
        raise OutputError(f"{path}: point clouds end in .ply or .pcd")
    with open(path, "wb") as stream:
        stream.write(header.encode("ascii"))
        stream.write(np.ascontiguousarray(points).tobytes())
