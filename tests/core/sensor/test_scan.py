"""Scans: validation of their points, origin and hit mask."""

import numpy as np
import pytest

from ehm.core.sensor.scan import Scan


def test_nan_and_inf_points_are_dropped_and_counted():
    points = np.array([[1.0, 0, 0], [np.nan, 0, 0], [0, np.inf, 0], [0, 2.0, 0]])
    scan = Scan(points, np.zeros(3))
    assert len(scan) == 2
    assert scan.n_dropped == 2


@pytest.mark.parametrize(
    ("points", "origin", "hit_mask", "message"),
    [
        (np.zeros((5, 4)), np.zeros(4), None, r"shape \(N, 2\) or \(N, 3\), got \(5, 4\)"),
        (np.zeros(5), np.zeros(3), None, r"got \(5,\)"),
        (np.zeros((0, 3)), np.zeros(3), None, "scan is empty"),
        (np.full((3, 3), np.nan), np.zeros(3), None, "3 non-finite dropped"),
        (np.ones((5, 3)), None, None, "origin is missing"),
        (np.ones((5, 3)), np.zeros(2), None, r"origin has shape \(2,\), points are 3D"),
        (np.ones((5, 3)), [0, np.nan, 0], None, "origin is not finite"),
        (np.ones((5, 3)), np.zeros(3), np.ones(4, bool), r"hit_mask has shape \(4,\)"),
        (np.ones((5, 3)), np.zeros(3), np.ones(5), "hit_mask must be boolean"),
    ],
)
def test_bad_scans_name_the_problem(points, origin, hit_mask, message):
    with pytest.raises(ValueError, match=message):
        Scan(points, origin, hit_mask)
