"""Every compiled kernel, compiled once. ehm's hot loops are Numba kernels, compiled at their
first call and cached on disk beside the package, so that later processes load them.
`warm_kernels` makes those first calls: it learns two small scans of a box room in 3D and in
2D and asks each family of queries and outputs once, so that no query stalls on compiling in
a user's later process."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from ehm.config import DEFAULT_RESOLUTION, MapConfig
from ehm.core.sensor.scan import Scan
from ehm.grid.blocks import block_mesh
from ehm.grid.navigation import navigation_grid, projected_navigation_grid
from ehm.hilbert_map import HilbertMap
from ehm.io.distance_file import DistanceGrid
from ehm.io.lzf import lzf_decompress
from ehm.pipeline import MappingPipeline
from ehm.viz.render import Camera, render_mesh

# Rays of each warm-up scan: a batch's worth (MapConfig.batch_rays) in 3D, so the second scan
# is learned with the first's evidence in the memory and its samples are gathered in parts,
# as a LiDAR sweep's are; a laser's in 2D.
RAYS = {3: 20_000, 2: 2_000}
# The box room, metres: half its width and its height; the sensor stands 1.2 m above the floor.
ROOM_HALF_WIDTH = 3.0
ROOM_HEIGHT = 2.5
SENSOR_HEIGHT = 1.2
# The queries of _queries whose kernels depend on the features (MapConfig.features).
FEATURE_QUERIES = ("point queries", "rays")


def room_scans(dim: int) -> list[Scan]:
    """Two scans of the box room, (RAYS[dim], dim) hits each, the second 0.5 m along x."""
    rng = np.random.default_rng(0)
    scans = []
    for shift in (0.0, 0.5):
        origin = np.zeros(dim)
        origin[0] = shift
        if dim == 3:
            origin[2] = SENSOR_HEIGHT
        directions = rng.normal(size=(RAYS[dim], dim))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        # The distance along each ray to the first wall (and floor or ceiling) it meets.
        low = np.full(dim, -ROOM_HALF_WIDTH)
        high = np.full(dim, ROOM_HALF_WIDTH)
        if dim == 3:
            low[2], high[2] = 0.0, ROOM_HEIGHT
        with np.errstate(divide="ignore"):
            reach = np.where(directions > 0, high - origin, low - origin) / directions
        scans.append(Scan(origin + directions * reach.min(axis=1, keepdims=True), origin))
    return scans


def _queries(hilbert_map: HilbertMap) -> list[tuple[str, Callable[[], object]]]:
    """The calls that compile each family of kernels once a map of the room exists."""
    dim = hilbert_map.dim
    rng = np.random.default_rng(1)
    low, high = hilbert_map.extent()
    points = rng.uniform(low, high, size=(500, dim))
    origins = np.repeat(hilbert_map.sensor_path[:1], 50, axis=0)
    directions = rng.normal(size=(50, dim))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    resolution = hilbert_map.config.resolution
    bounds = np.stack([low, high])

    def point_queries() -> None:
        hilbert_map.occupancy(points, return_std=True)
        # Points mostly far from any cluster, which the search first sifts by a table of counts.
        hilbert_map.occupancy(rng.uniform(low - 20.0, high + 20.0, size=(20_000, dim)))
        hilbert_map.occupancy(points, mode="exact")
        hilbert_map.gradient(points)
        hilbert_map.known(points)

    def rays() -> None:
        hilbert_map.raycast(origins, directions, 4.0)
        hilbert_map.segment_free(origins, origins + directions)

    def distances() -> None:
        DistanceGrid.at_centres(hilbert_map, low, 0.2, (4,) * dim)

    def grids() -> None:
        hilbert_map.grid(bounds, resolution, std=True)
        list(hilbert_map.grid_blocks(None, resolution))

    def outputs() -> None:
        if dim == 3:
            vertices, faces = block_mesh(hilbert_map.snapshot(), resolution)
            render_mesh(vertices, faces, Camera(width=64, height=48), (0.0, ROOM_HEIGHT))
            heights = (0.3, 2.0)
            projected_navigation_grid(hilbert_map, heights, bounds[:, :2], 0.1)
        else:
            navigation_grid(hilbert_map, bounds, 0.1)

    return [
        ("point queries", point_queries),
        ("rays", rays),
        ("distances", distances),
        ("grids", grids),
        ("meshes and pictures" if dim == 3 else "navigation grids", outputs),
    ]


def warm_kernels(report: Callable[[str], None] | None = None) -> float:
    """Compile (or load from the cache) every kernel a map's learning, queries and outputs
    use, in 3D and 2D, calling `report(step)` as each step starts. Returns the seconds taken:
    minutes the first time after install, a few seconds once the cache holds them."""
    start = time.perf_counter()
    say = report or (lambda step: None)
    for dim in (3, 2):
        say(f"learning {dim}D scans")
        hilbert_map = MappingPipeline(room_scans(dim), HilbertMap()).run().hilbert_map
        for step, call in _queries(hilbert_map):
            say(f"{step} ({dim}D)")
            call()
        # The real-time profile learns and answers with other features (MapConfig.features);
        # what reads every kernel (grids, outputs) is the same code.
        say(f"learning {dim}D scans in real time")
        realtime = HilbertMap(MapConfig.for_resolution(DEFAULT_RESOLUTION, "realtime"))
        MappingPipeline(room_scans(dim), realtime).run()
        for step, call in _queries(realtime):
            if step in FEATURE_QUERIES:
                say(f"{step} ({dim}D, real time)")
                call()
    say("compressed point clouds")
    lzf_decompress(bytes([2, 1, 2, 3]), 3)  # one literal run of three bytes
    return time.perf_counter() - start
