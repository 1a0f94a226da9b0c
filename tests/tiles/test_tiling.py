"""Cutting the world into tiles: learn boxes, blending weights, clipped scans."""

import numpy as np
import pytest

from ehm.core.sensor.boxes import points_in_box
from ehm.core.sensor.scan import Scan
from ehm.errors import SettingsError
from ehm.tiles.tiling import Tiling, scan_box


@pytest.mark.parametrize("dim", [2, 3])
def test_blend_weights_sum_to_one_over_tiles_that_learned_each_point(rng, dim):
    tiling = Tiling(10.0, 1.5)
    points = rng.uniform(-30.0, 30.0, (5000, dim))
    points[:50, 0] = np.round(points[:50, 0] / 10.0 + 0.5) * 10.0 - 5.0  # on borders
    rows, keys, weights = tiling.blend(points)
    np.testing.assert_allclose(np.bincount(rows, weights, len(points)), 1.0, atol=1e-12)
    assert np.all(weights > 0) and np.all(weights <= 1.0)
    assert np.bincount(rows).max() <= 2**dim
    for row, key, weight in zip(rows, keys, weights, strict=True):
        assert points_in_box(points[row : row + 1], tiling.learn_box(tuple(key)))[0]
        assert tiling.weights(points[row : row + 1], tuple(key))[0] == pytest.approx(weight)
    # On a border both tiles weigh a half; `overlap` inside a core, only that tile counts.
    on_border = np.isin(rows, np.arange(50))
    assert np.all(np.bincount(rows[on_border]) >= 2)


def test_blend_weights_change_smoothly_across_a_border():
    tiling = Tiling(10.0, 2.0)
    x = np.linspace(-1.0, 11.0, 2401)
    points = np.column_stack([x, np.zeros_like(x)])
    weight = tiling.weights(points, (0, 0))
    assert weight[x <= 3.0].min() == pytest.approx(1.0)
    assert weight[np.isclose(x, 5.0)][0] == pytest.approx(0.5)
    assert weight[x >= 7.0].max() == pytest.approx(0.0)
    # Smoothstep: the steepest slope is 1.5 / (2 overlap), and no kink: between neighbours
    # the slope changes by at most the largest curvature, 6 / (2 overlap)^2, times the step.
    slope = np.diff(weight) / np.diff(x)
    assert np.abs(slope).max() == pytest.approx(1.5 / 4.0, rel=1e-3)
    assert np.abs(np.diff(slope)).max() <= 6.0 / 4.0**2 * (x[1] - x[0]) * 1.001


def test_keys_meeting_a_box_are_exactly_the_tiles_whose_learn_box_meets_it(rng):
    tiling = Tiling(4.0, 1.0)
    for _ in range(50):
        low = rng.uniform(-10.0, 10.0, 3)
        box = np.stack([low, low + rng.uniform(0.1, 9.0, 3)])
        found = set(tiling.keys_meeting(box))
        for key in np.ndindex(9, 9, 9):
            key = tuple(int(k) - 4 for k in key)
            learn = tiling.learn_box(key)
            meets = bool(np.all(learn[0] <= box[1]) and np.all(learn[1] >= box[0]))
            assert (key in found) == meets, key


def test_clip_keeps_the_rays_that_cross_a_tile(rng):
    tiling = Tiling(5.0, 0.5)
    origin = np.array([0.0, 0.0])
    ends = rng.uniform(-12.0, 12.0, (400, 2))
    scan = Scan(ends, origin, rng.random(400) < 0.5)
    key = (1, 0)
    part = tiling.clip(scan, key)
    box = tiling.learn_box(key)
    marched = origin + np.linspace(0.0, 1.0, 2001)[:, None, None] * (ends - origin)
    crosses = np.any(np.all((marched >= box[0]) & (marched <= box[1]), axis=2), axis=0)
    found = {tuple(p) for p in part.points_world}
    assert found == {tuple(p) for p in ends[crosses]}
    assert tiling.clip(scan, (5, 5)) is None
    np.testing.assert_allclose(scan_box(scan), [ends.min(axis=0), ends.max(axis=0)])


@pytest.mark.parametrize(
    ("size", "overlap", "message"),
    [(0.0, 1.0, "tile size"), (10.0, 0.0, "overlap"), (10.0, 6.0, "at most half")],
)
def test_bad_tilings_are_refused(size, overlap, message):
    with pytest.raises(SettingsError, match=message):
        Tiling(size, overlap)


@pytest.mark.parametrize("dim", [2, 3])
def test_weight_gradients_are_the_derivatives_of_the_weights(rng, dim):
    tiling = Tiling(4.0, 1.0)
    key = (0,) * dim
    points = rng.uniform(-3.5, 3.5, (4000, dim))
    step = 1e-6
    numeric = np.column_stack(
        [
            (tiling.weights(points + step * np.eye(dim)[a], key)
             - tiling.weights(points - step * np.eye(dim)[a], key)) / (2 * step)
            for a in range(dim)
        ]
    )  # fmt: skip
    analytic = tiling.weight_gradients(points, key)
    assert np.abs(analytic).max() > 0.5
    np.testing.assert_allclose(analytic, numeric, atol=1e-6)
