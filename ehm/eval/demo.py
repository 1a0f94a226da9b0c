"""The demo: the virtual room seen by one simulated 3D LiDAR scan, mapped, scored against the
room's exact occupancy, and written out as a map, occupancy slices, a mesh and a picture."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ehm.core.timing import StageTimer
from ehm.eval.datasets import virtual_room
from ehm.eval.metrics import Scores, score
from ehm.eval.protocol import exact_test_points
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.hilbert_map import HilbertMap
from ehm.io.ply import write_ply_mesh
from ehm.pipeline import MappingObserver, MappingPipeline, MappingRun
from ehm.viz.colors import vertex_colors
from ehm.viz.pictures import mesh_picture, occupancy_slices
from ehm.viz.render import Camera

# Horizontal slices through the room's furniture, metres.
SLICE_HEIGHTS = (0.3, 0.75, 1.2, 2.0)
# The mesh picture leaves out the ceiling, to look into the room.
CUT_ABOVE = 2.2


@dataclass(frozen=True)
class ExactScore:
    """Scores of the map at `n` test points of which a share `occupied` is occupied."""

    n: int
    occupied: float
    scores: Scores


@dataclass(frozen=True)
class DemoResult:
    """run: the mapping; exact: scores against the exact occupancy, by test set ('near
    surfaces', 'uniform, observed region'); steps: seconds per step of the demo; grid: the
    0.05 m grid; n_faces: faces of its mesh; written: the files, in order."""

    run: MappingRun
    exact: dict[str, ExactScore]
    steps: dict[str, float]
    grid: OccupancyGrid
    n_faces: int
    written: list[Path]


def run_demo(out: Path, seed: int = 0, observers: Sequence[MappingObserver] = ()) -> DemoResult:
    """Simulate the virtual room (seed draws the range noise and seeds the map), map it and
    write virtual_room.ehm, virtual_room_slices.png, virtual_room.ply and
    virtual_room_mesh.png into `out` (made when missing)."""
    out.mkdir(parents=True, exist_ok=True)
    timer = StageTimer()
    with timer("simulate LiDAR"):
        data = virtual_room(seed=seed)
    run = MappingPipeline(data.scans, HilbertMap(seed=seed), observers=observers).run()
    hilbert_map = run.hilbert_map

    low, high = data.scene.box_min.min(axis=0), data.scene.box_max.max(axis=0)
    near, uniform = exact_test_points(
        data.scans,
        low,
        high,
        0.5,
        200_000,
        hilbert_map.config.surface_margin,
        np.random.default_rng(seed + 1),
    )
    exact = {}
    for name, points in (("near surfaces", near), ("uniform, observed region", uniform)):
        with timer(f"query {name}"):
            probability = hilbert_map.occupancy(points)
        labels = data.scene.occupied(points)
        exact[name] = ExactScore(len(points), float(labels.mean()), score(labels, probability))

    paths = [out / f"virtual_room{suffix}" for suffix in (".ehm", "_slices.png", ".ply")]
    paths.append(out / "virtual_room_mesh.png")
    map_path, slices_path, mesh_path, picture_path = paths
    with timer("save map"):
        hilbert_map.save(map_path)
    with timer("draw slices"):
        occupancy_slices(hilbert_map, low, high, slices_path, data.scene.occupied, SLICE_HEIGHTS)
    with timer("grid (0.05 m)"):
        grid = hilbert_map.grid(resolution=0.05)
    with timer("mesh"):
        vertices, faces = grid.mesh()
    with timer("save mesh"):
        write_ply_mesh(mesh_path, vertices, faces, vertex_colors(vertices))
    with timer("render mesh"):
        title = f"virtual room, mesh at p = 0.5 cut at {CUT_ABOVE} m"
        camera = Camera(azimuth=-60.0, elevation=55.0)
        mesh_picture(vertices, faces, picture_path, camera, cut_above=CUT_ABOVE, title=title)
    return DemoResult(run, exact, dict(timer.seconds), grid, len(faces), paths)
