"""The real data sets, read from the shared data folder (skipped where absent)."""

import numpy as np

from ehm.eval.datasets import real


def test_real_octomap_scan(real_data):
    (scan,) = real_data(real.octomap_scan)
    assert len(scan) == 88206
    np.testing.assert_allclose(scan.origin, [0.035, 0.0, 0.513])


def test_real_pcl_room(real_data):
    scans = real_data(real.pcl_room)
    assert len(scans) == 2
    for scan in scans:
        ranges = np.linalg.norm(scan.points_world - scan.origin, axis=1)
        assert 80_000 < len(scan) <= 112_624 and ranges.min() >= 0.3


def test_real_tum_sequence(real_data):
    scans = real_data(real.tum_fr2_pioneer_slam2)
    assert len(scans) == 10
    assert all(10_000 < len(s) <= 640 * 480 // 4 for s in scans)


def test_real_intel_lab(real_data):
    scans = real_data(real.intel_lab)
    assert len(scans) == 910 and all(s.dim == 2 for s in scans)
    ranges = np.concatenate([np.linalg.norm(s.points_world - s.origin, axis=1) for s in scans])
    assert ranges.max() < 81.0
