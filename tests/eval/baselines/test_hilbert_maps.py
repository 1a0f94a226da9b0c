"""Original Hilbert maps: Fourier, Nystrom and sparse-grid features."""

import numpy as np
import pytest

from ehm.core.model.kernels import sparse_kernel_reference
from ehm.eval.baselines.hilbert_maps import (
    FourierFeatures,
    GridFeatures,
    HilbertMapsSettings,
    NystromFeatures,
    SparseRows,
    logistic_sgd,
    rbf_kernel,
)


def test_fourier_features_approximate_the_rbf_kernel(rng):
    features = FourierFeatures(3, 20_000, 0.5, rng)
    points = rng.uniform(-0.5, 0.5, (30, 3))
    phi = features(points)
    np.testing.assert_allclose(phi @ phi.T, rbf_kernel(points, points, 0.5), atol=0.03)


def test_nystrom_features_reproduce_the_kernel_on_inducing_points(rng):
    samples = rng.uniform(-1, 1, (400, 3))
    features = NystromFeatures(samples, 50, 0.5, rng)
    phi = features(features.inducing)
    expected = rbf_kernel(features.inducing, features.inducing, 0.5)
    np.testing.assert_allclose(phi @ phi.T, expected, atol=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_grid_features_equal_the_kernel_at_every_grid_node(dim, rng):
    samples = rng.uniform(-1, 1, (200, dim))
    features = GridFeatures(samples, spacing=0.2, radius=0.3, max_points=10**6)
    phi = features(samples[:40])
    nodes = np.stack(np.unravel_index(np.arange(features.size), features.shape), 1)
    positions = features.low + nodes * features.spacing
    distance = np.linalg.norm(samples[:40, None, :] - positions[None], axis=2)
    expected = sparse_kernel_reference(distance / features.radius)
    dense = np.zeros((40, features.size))
    np.add.at(dense, (np.arange(40)[:, None], phi.columns), phi.values)
    np.testing.assert_allclose(dense, expected, atol=1e-12)


def test_grid_features_refuse_grids_past_the_limit(rng):
    with pytest.raises(ValueError, match="max_grid_points"):
        GridFeatures(rng.uniform(-10, 10, (50, 3)), spacing=0.1, radius=0.15, max_points=1000)


def test_sgd_gives_the_same_weights_for_sparse_and_dense_features(rng):
    points = rng.uniform(-1, 1, (600, 2))
    labels = points[:, 0] > 0.2
    grid = GridFeatures(points, spacing=0.25, radius=0.4, max_points=10**6)

    def dense(batch):
        rows = grid(batch)
        matrix = np.zeros((len(batch), grid.size))
        np.add.at(matrix, (np.arange(len(batch))[:, None], rows.columns), rows.values)
        return matrix

    dense.size = grid.size
    settings = HilbertMapsSettings(batch_size=32, epochs=2, l2=0.0)
    sparse_weights = logistic_sgd(grid, points, labels, settings, np.random.default_rng(1))
    dense_weights = logistic_sgd(dense, points, labels, settings, np.random.default_rng(1))
    np.testing.assert_allclose(sparse_weights, dense_weights, atol=1e-12)
    p = 1 / (1 + np.exp(-(grid(points) @ sparse_weights)))
    assert np.mean((p > 0.5) == labels) > 0.9


def test_sparse_rows_multiply_like_the_dense_matrix():
    rows = SparseRows(np.array([[0, 2], [1, 1]]), np.array([[0.5, 2.0], [1.0, 3.0]]))
    np.testing.assert_allclose(rows @ np.array([1.0, 10.0, 100.0]), [200.5, 40.0])
