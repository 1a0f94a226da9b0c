"""Scans wait for a batch of rays, and every scan's origin is kept in order."""

import numpy as np
import pytest

from ehm.core.sensor.scan import Scan
from ehm.core.sensor.waiting_scans import WaitingScans, check_scan
from ehm.errors import InputError


def _scan(rng, n, origin):
    return Scan(rng.uniform(-3.0, 3.0, (n, 3)), np.asarray(origin, dtype=float))


def test_scans_wait_until_they_hold_a_batch(rng):
    waiting = WaitingScans(batch_rays=250)
    assert waiting.dim is None and len(waiting) == 0
    assert not waiting.add(_scan(rng, 100, [0, 0, 1]))
    assert not waiting.add(_scan(rng, 100, [1, 0, 1]))
    assert waiting.add(_scan(rng, 100, [2, 0, 1]))
    assert waiting.dim == 3 and len(waiting) == 3
    assert waiting.nbytes == 3 * (100 * 3 * 8 + 100) + 3 * 3 * 8
    taken = waiting.take()
    assert [scan.origin[0] for scan in taken] == [0.0, 1.0, 2.0] and len(waiting) == 0
    assert not waiting.add(_scan(rng, 100, [3, 0, 1]))  # the count starts again
    np.testing.assert_array_equal(waiting.sensor_path(3)[:, 0], [0.0, 1.0, 2.0, 3.0])
    assert WaitingScans(0).sensor_path(2).shape == (0, 2)


def test_restored_scans_count_their_rays(rng):
    kept = [_scan(rng, 100, [0, 0, 1]), _scan(rng, 100, [1, 0, 1])]
    waiting = WaitingScans(250, kept, [scan.origin for scan in kept])
    assert waiting.add(_scan(rng, 50, [2, 0, 1]))


def test_bad_scans_are_named(rng):
    scan = _scan(rng, 10, [0, 0, 1])
    assert check_scan(scan, "scan", 3, "the map", None) is scan
    with pytest.raises(InputError, match=r"scan 2: expected ehm\.Scan, got list"):
        check_scan([1, 2], "scan 2", None, "scan 0", None)
    with pytest.raises(InputError, match="scan points are 3D, the map is 2D"):
        check_scan(scan, "scan", 2, "the map", None)
    with pytest.raises(InputError, match=r"scan has no time stamp.* 5.0 s \(MapConfig"):
        check_scan(scan, "scan", 3, "the map", 5.0)
