"""The occupancy's uncertainty: the compiled curvature sum against its NumPy twin, the
standard deviation of the sigmoid against numerical integration, and the background's share."""

import numpy as np
import pytest
from scipy import integrate

from ehm.core.weights.uncertainty import (
    curvature_sum,
    curvature_sum_reference,
    logit_variance,
    occupancy_std,
)


def test_compiled_curvature_matches_reference(rng, sparse_batch):
    n, n_clusters = 400, 50
    indptr, rows, values, _ = sparse_batch(rng, n, 6, 30, n_clusters)
    sample_weights = rng.uniform(0.5, 2.0, n)
    sample_weights[::3] = 0.0  # samples that add nothing, as replayed ones
    weights = rng.normal(size=n_clusters)
    start = rng.uniform(1.0, 3.0, n_clusters)
    compiled, reference = start.copy(), start.copy()
    curvature_sum(indptr, rows, values, sample_weights, weights, -0.4, compiled)
    curvature_sum_reference(indptr, rows, values, sample_weights, weights, -0.4, reference)
    np.testing.assert_allclose(compiled, reference, rtol=1e-12)
    assert np.all(compiled >= start) and np.count_nonzero(compiled > start) > 0.9 * n_clusters


def test_curvature_of_one_feature_is_the_fisher_information():
    # 100 samples with phi = 0.5 at a weight of 0 and bias 0: p = 0.5, so each adds 0.25 * 0.25.
    precision = np.ones(1)
    curvature_sum(
        np.arange(101),
        np.zeros(100, dtype=np.int64),
        np.full(100, 0.5),
        np.ones(100),
        np.zeros(1),
        0.0,
        precision,
    )
    assert precision[0] == pytest.approx(1.0 + 100 * 0.25 * 0.25)


def exact_std(mean: float, variance: float) -> float:
    """Standard deviation of sigmoid(z), z ~ N(mean, variance), by Simpson's rule on a fine grid."""
    z = mean + np.sqrt(variance) * np.linspace(-12.0, 12.0, 200_001)
    density = np.exp(-((z - mean) ** 2) / (2 * variance)) / np.sqrt(2 * np.pi * variance)
    sigmoid = 0.5 * (1.0 + np.tanh(z / 2.0))
    first = integrate.simpson(sigmoid * density, x=z)
    second = integrate.simpson(sigmoid**2 * density, x=z)
    return float(np.sqrt(second - first**2))


def test_std_of_the_sigmoid_matches_numerical_integration():
    means = np.array([0.0, 1.5, -3.0, 6.0, 0.5, -2.0])
    variances = np.array([1.0, 0.05, 4.0, 12.0, 0.3, 8.0])
    expected = [exact_std(m, v) for m, v in zip(means, variances, strict=True)]
    np.testing.assert_allclose(occupancy_std(means, variances), expected, atol=5e-5)
    # No variance, no spread; a NaN mean stays NaN.
    assert occupancy_std(np.array([2.0]), np.array([0.0]))[0] < 1e-7
    assert np.isnan(occupancy_std(np.array([np.nan]), np.array([1.0]))[0])


def test_background_takes_what_the_kernels_leave_at_the_prior():
    square_over_precision = np.array([0.0, 0.0, 0.02, 0.3])
    kernel_sum = np.array([0.0, 0.25, 1.0, 2.4])
    variance = logit_variance(square_over_precision, kernel_sum, prior_precision=2.0)
    # Nothing reaches: the prior's variance, 1 / 2. A quarter covered: 0.75^2 of it.
    np.testing.assert_allclose(variance, [0.5, 0.75**2 / 2.0, 0.02, 0.3])
