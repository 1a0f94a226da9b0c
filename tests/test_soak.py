"""Long runs through one map with saves along the way end where a map never saved does."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import ehm
from ehm.eval.datasets.simulated import corridor_2d, floor_plan_2d, warehouse_drive

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.parametrize(
    ("scans", "save_every", "settings"),
    [
        (lambda: corridor_2d(n_scans=300, length=20.0).scans, 37, {}),
        (lambda: warehouse_drive(n_scans=8, rings=8, azimuths=256).scans, 3, {}),
        # Driven twice, scan by scan, its replay drawn beyond half the batch from the second
        # scan on: the draws follow the saved random state.
        (lambda: 2 * floor_plan_2d(seed=0).scans, 3, {"batch_rays": 0, "replay_cap": 0.5}),
    ],
)
def test_saving_and_loading_along_the_way_changes_nothing(tmp_path, scans, save_every, settings):
    saved, plain = ehm.HilbertMap(**settings), ehm.HilbertMap(**settings)
    for index, scan in enumerate(scans(), start=1):
        saved.integrate_scan(scan)
        plain.integrate_scan(scan)
        if index % save_every == 0:
            saved.save(tmp_path / "m.ehm")
            saved = ehm.load(tmp_path / "m.ehm")
    saved.flush()
    plain.flush()
    for name, array in plain.clusters_.arrays().items():
        np.testing.assert_array_equal(getattr(saved.clusters_, name), array, err_msg=name)
    low, high = plain.clusters_.means.min(axis=0), plain.clusters_.means.max(axis=0)
    points = np.random.default_rng(0).uniform(low, high, (5000, plain.dim))
    np.testing.assert_array_equal(saved.occupancy(points), plain.occupancy(points))


@pytest.mark.slow
def test_the_soak_benchmark_ends_with_equal_maps():
    """20,000 2D scans and 200 3D scans (several minutes): benchmarks/soak.py."""
    result = subprocess.run(
        [sys.executable, str(BENCHMARKS / "soak.py")], capture_output=True, text=True, check=True
    )
    assert result.stdout.count("final map equal to the one never saved: yes") == 2
