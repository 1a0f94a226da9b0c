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


def test_real_icl_living_room_with_and_without_noise(real_data):
    """Five rendered frames at their own scale (0.96-2.70 m); the noisy twin moves each point
    along its ray by 1 cm (sd), nothing else."""
    clean = real_data(real.icl_living_room)
    noisy = real_data(lambda: real.icl_living_room(noise_std=0.01))
    assert len(clean) == len(noisy) == 5
    for exact, moved in zip(clean, noisy, strict=True):
        np.testing.assert_array_equal(exact.origin, moved.origin)
        ranges = np.linalg.norm(exact.points_world - exact.origin, axis=1)
        assert ranges.min() > 0.9 and ranges.max() < 3.5
        offsets = moved.points_world - exact.points_world
        along = np.einsum("nd,nd->n", offsets, exact.points_world - exact.origin) / ranges
        np.testing.assert_allclose(np.abs(along), np.linalg.norm(offsets, axis=1), atol=1e-9)
        assert 0.009 < np.std(along) < 0.011
