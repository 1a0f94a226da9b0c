"""The gradient of the occupancy log-odds: compiled against NumPy, analytic against finite
differences."""

import numpy as np
import pytest

import ehm
from ehm.core.model.kernels import sparse_kernel_reference
from ehm.core.queries.gradient import (
    logit_gradients,
    logit_gradients_reference,
    sparse_kernel_slope_reference,
)


def test_kernel_slope_is_the_derivative_of_the_kernel():
    r = np.linspace(0.0, 1.2, 241)
    step = 1e-6
    numeric = (sparse_kernel_reference(r + step) - sparse_kernel_reference(r - step)) / (2 * step)
    np.testing.assert_allclose(sparse_kernel_slope_reference(r), numeric, atol=1e-6)
    assert sparse_kernel_slope_reference(np.array([0.0, 1.0]))[0] == 0.0
    assert abs(sparse_kernel_slope_reference(np.array([1.0 - 1e-9]))[0]) < 1e-8


def test_compiled_gradients_agree_with_numpy(rng, random_clusters):
    clusters = random_clusters(rng, n=300, extent=4.0)
    weights = rng.normal(size=len(clusters))
    # Every point lies near the first of its 12 clusters; the others are drawn at random, and
    # most of their kernels do not reach it.
    rows = rng.integers(0, len(clusters), (2000, 12))
    points = clusters.means[rows[:, 0]] + rng.normal(0.0, 0.05, (2000, 3))
    rows = rows.ravel()
    indptr = np.arange(0, 12 * 2001, 12, dtype=np.int64)
    arguments = (points, indptr, rows, clusters.means, clusters.transforms)
    arguments += (clusters.planar_kernel, weights)
    compiled = logit_gradients(*arguments)
    assert np.count_nonzero(compiled.any(axis=1)) > 250  # half the clusters are planar
    np.testing.assert_allclose(compiled, logit_gradients_reference(*arguments), atol=1e-12)


def finite_differences(hilbert_map, points, mode=None, step=1e-5):
    columns = []
    for axis in range(points.shape[1]):
        offset = np.zeros(points.shape[1])
        offset[axis] = step
        ahead = hilbert_map.decision_function(points + offset, mode)
        behind = hilbert_map.decision_function(points - offset, mode)
        columns.append((ahead - behind) / (2 * step))
    return np.column_stack(columns)


def test_gradient_matches_finite_differences_of_the_log_odds(room):
    hilbert_map = ehm.HilbertMap(features="support", planar_kernel=False).fit(room.scans[:1])
    rng = np.random.default_rng(3)
    points = rng.uniform([-4.0, -3.0, 0.1], [4.0, 3.0, 2.4], (3000, 3))
    analytic = hilbert_map.gradient(points)
    numeric = finite_differences(hilbert_map, points)
    assert np.abs(analytic).max() > 1.0  # the surfaces are in the box
    np.testing.assert_allclose(analytic, numeric, atol=1e-4 * np.abs(numeric).max())


@pytest.mark.parametrize("overrides", [{}, {"features": "nearest"}])
def test_gradient_points_into_walls_and_is_nan_where_points_are(room, overrides):
    """With the defaults (planar kernels, flat) and with nearest features (the kernels taken
    change from point to point): the finite differences agree wherever they are smooth, and
    the gradient leads from the free room toward the wall at x = 4.5."""
    hilbert_map = ehm.HilbertMap(**overrides).fit(room.scans[:1])
    rng = np.random.default_rng(4)
    points = rng.uniform([-4.0, -3.0, 0.1], [4.0, 3.0, 2.4], (3000, 3))
    analytic = hilbert_map.gradient(points, mode="exact")
    numeric = finite_differences(hilbert_map, points, "exact")
    coarse = finite_differences(hilbert_map, points, "exact", step=1e-4)
    smooth = np.all(np.abs(numeric - coarse) < 1e-3 * (1 + np.abs(numeric)), axis=1)
    assert smooth.mean() > 0.8
    np.testing.assert_allclose(analytic[smooth], numeric[smooth], atol=1e-3, rtol=1e-3)
    approach = np.column_stack([np.linspace(3.6, 4.3, 8), np.zeros(8), np.full(8, 1.2)])
    assert np.median(hilbert_map.gradient(approach)[:, 0]) > 0
    with_nan = hilbert_map.gradient(np.array([[0.0, 0.0, np.nan], [0.0, 0.0, 1.0]]))
    assert np.isnan(with_nan[0]).all() and np.isfinite(with_nan[1]).all()
    with pytest.raises(ehm.InputError, match="query points must have shape"):
        hilbert_map.gradient(np.zeros((2, 2)))
