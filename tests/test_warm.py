"""Compiling every kernel once: `ehm warm` and the first `ehm demo`."""

import os
import subprocess
import sys

import numpy as np
import pytest

from ehm.warm import ROOM_HALF_WIDTH, ROOM_HEIGHT, room_scans, warm_kernels


@pytest.mark.parametrize("dim", [2, 3])
def test_the_room_scans_end_on_its_walls_floor_and_ceiling(dim):
    for scan in room_scans(dim):
        hits = scan.points_world
        on_wall = np.isclose(np.abs(hits[:, :2]), ROOM_HALF_WIDTH).any(axis=1)
        if dim == 3:
            on_wall |= np.isclose(hits[:, 2], 0.0) | np.isclose(hits[:, 2], ROOM_HEIGHT)
        assert on_wall.all()
        assert np.all(np.abs(hits) <= max(ROOM_HALF_WIDTH, ROOM_HEIGHT) + 1e-9)


def test_warming_reports_each_step_in_3d_then_2d():
    steps = []
    seconds = warm_kernels(steps.append)
    assert seconds > 0
    assert steps[0] == "learning 3D scans" and "learning 2D scans" in steps
    assert steps.index("meshes and pictures (3D)") < steps.index("learning 2D scans")
    assert "rays (2D)" in steps and "distances (2D)" in steps and "navigation grids (2D)" in steps
    assert "point queries (3D, real time)" in steps and "rays (2D, real time)" in steps


# A new process's first calls, 2D and 3D, across queries and outputs.
FIRST_CALLS = """
import numpy as np
import ehm
from ehm.grid.blocks import block_mesh
from ehm.warm import room_scans
for dim in (3, 2):
    hilbert_map = ehm.HilbertMap().fit(room_scans(dim)[::-1])
    points = np.random.default_rng(5).uniform(-4.0, 4.0, size=(3000, dim))
    hilbert_map.occupancy(points, return_std=True)
    hilbert_map.raycast(points[:50] * 0.1, points[50:100] / 4.0, 3.0)
    hilbert_map.distance(points[:100])
    hilbert_map.grid(np.stack([points.min(axis=0), points.max(axis=0)]), 0.2)
    if dim == 3:
        block_mesh(hilbert_map.snapshot(), 0.1)
    realtime = ehm.HilbertMap(resolution=0.05, profile="realtime").fit(room_scans(dim))
    realtime.occupancy(points, return_std=True)
    realtime.raycast(points[:50] * 0.1, points[50:100] / 4.0, 3.0)
"""


@pytest.mark.slow
def test_after_warming_a_new_process_compiles_nothing(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path), "NUMBA_DEBUG_CACHE": "1"}
    warm = [sys.executable, "-c", "from ehm.warm import warm_kernels; warm_kernels()"]
    subprocess.run(warm, check=True, capture_output=True, env=env)
    run = subprocess.run(
        [sys.executable, "-c", FIRST_CALLS], check=True, capture_output=True, text=True, env=env
    )
    assert "data saved to" not in run.stdout, run.stdout
