"""The uncertainty of the occupancy: a Gaussian posterior over the weights (Laplace), and the
standard deviation of the occupancy probability it implies.

Each weight w_m has a diagonal posterior precision
    lambda_m = prior_precision + sum_i c_i p_i (1 - p_i) phi_im^2,
the curvature of the logistic loss (Eq. 2) at the learned weights, summed over every sample
the map has learned, each once (replayed samples are not counted again); c_i is the weight of
sample i's class and p_i its predicted occupancy. Weights of well-observed places have high
precision.

At a point x the log-odds z = w^T phi(x) then have variance sum_m phi_m(x)^2 / lambda_m. A
point that no kernel reaches would have none, so where the kernels add up to less than 1,
c(x) = sum_m phi_m(x) < 1 (between and beyond the clusters), the rest, 1 - c(x), is the share
of a background feature whose weight nothing observes (precision `prior_precision`):
    var z = sum_m phi_m(x)^2 / lambda_m + max(0, 1 - c(x))^2 / prior_precision.
Before anything is learned every point has the prior variance 1 / prior_precision, and where
nothing was observed it keeps it. The standard deviation of the occupancy probability
sigmoid(z), z ~ N(mean, var), comes from Gauss-Hermite quadrature. The background's share
follows the kernels' sum rather than the norm of phi: at the median hit of the virtual room
the kernels add up to 0.82 and their squares to 0.25, so the norm would leave three quarters
of the prior's variance at observed surfaces, the sum 0.03 of it.
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.core.model.features import SparseFeatures
from ehm.core.primitives.logistic import sigmoid, sigmoid_scalar

# Gauss-Hermite nodes and weights for E[f(z)], z ~ N(mean, variance): exact for polynomials
# of degree up to 127; the standard deviation of the sigmoid comes within 4e-5 of the exact one
# for log-odds variances up to 12, within 0.006 up to 100.
_NODES, _WEIGHTS = np.polynomial.hermite.hermgauss(64)


def add_curvature(
    features: SparseFeatures,
    sample_weights: np.ndarray,
    weights: np.ndarray,
    bias: float,
    precision: np.ndarray,
) -> None:
    """Add the curvature of the loss of samples with `features` at `weights` and `bias` to
    `precision` ((M,) float64, in place): lambda_m += c_i p_i (1 - p_i) phi_im^2, with c_i
    `sample_weights` (n,) float64."""
    curvature_sum(
        features.indptr,
        features.rows,
        features.values,
        sample_weights,
        weights,
        bias,
        precision,
    )


# Parts of the samples whose curvature curvature_sum adds up apart, on as many threads as
# there are, before adding the parts' sums: a fixed number, so the sums do not depend on the
# threads.
CURVATURE_PARTS = 2


@numba.njit(cache=True, parallel=True)
def curvature_sum(
    indptr, rows, values, sample_weights, weights, bias, precision
):  # pragma: no cover - compiled
    """Compiled core of `add_curvature`, on the features' compressed rows (see
    SparseFeatures)."""
    n = len(indptr) - 1
    sums = np.zeros((CURVATURE_PARTS, len(precision)))
    for part in numba.prange(CURVATURE_PARTS):
        for i in range(n * part // CURVATURE_PARTS, n * (part + 1) // CURVATURE_PARTS):
            if sample_weights[i] == 0.0:  # replayed samples, counted when they were new
                continue
            score = bias
            for e in range(indptr[i], indptr[i + 1]):
                score += weights[rows[e]] * values[e]
            p = sigmoid_scalar(score)
            curvature = sample_weights[i] * p * (1.0 - p)
            for e in range(indptr[i], indptr[i + 1]):
                sums[part, rows[e]] += curvature * values[e] * values[e]
    for part in range(CURVATURE_PARTS):
        precision += sums[part]


def curvature_sum_reference(
    indptr: np.ndarray,
    rows: np.ndarray,
    values: np.ndarray,
    sample_weights: np.ndarray,
    weights: np.ndarray,
    bias: float,
    precision: np.ndarray,
) -> None:
    """Plain NumPy twin of `curvature_sum`."""
    sample = np.repeat(np.arange(len(indptr) - 1), np.diff(indptr))
    p = sigmoid(bias + np.bincount(sample, weights[rows] * values, len(indptr) - 1))
    np.add.at(precision, rows, (sample_weights * p * (1.0 - p))[sample] * values**2)


def logit_variance(
    square_over_precision: np.ndarray, kernel_sum: np.ndarray, prior_precision: float
) -> np.ndarray:
    """Variance of the log-odds from sum_m phi_m^2 / lambda_m and c = sum_m phi_m at each
    point (arrays of one shape), the background's share at the prior precision."""
    background = np.maximum(0.0, 1.0 - kernel_sum)
    return square_over_precision + background * background / prior_precision


def occupancy_std(log_odds: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """Standard deviation of sigmoid(z) for z ~ N(log_odds, variance), elementwise (arrays of
    one shape, float64); NaN where log_odds is NaN."""
    log_odds = np.asarray(log_odds, dtype=np.float64)
    spread = np.sqrt(2.0 * np.maximum(np.asarray(variance, dtype=np.float64), 0.0))
    first = np.zeros(np.broadcast(log_odds, spread).shape)
    second = np.zeros_like(first)
    for node, weight in zip(_NODES, _WEIGHTS / np.sqrt(np.pi), strict=True):
        p = sigmoid(log_odds + spread * node)
        first += weight * p
        second += weight * p * p
    return np.sqrt(np.maximum(second - first * first, 0.0))
