"""The gradient of the occupancy log-odds with respect to position: sum_m w_m grad k_m(x).

For the localized length-scale kernel, with u = T_m (x - mu_m) and r = |u|,
    k_SP(r) = (2 + cos 2 pi r) / 3 (1 - r) + sin(2 pi r) / (2 pi)        (Eq. 8)
    dk_SP/dr = (2 cos 2 pi r - 2) / 3 - 2 pi sin(2 pi r) (1 - r) / 3
    grad_x k = dk/dr T_m^T u / r,
which is 0 at the centre (r = 0) and at the support's edge (r = 1): the kernel is smooth. The
planar-surface kernel (Eq. 13) is 1 inside its box and 0 outside; its gradient is 0 wherever
it is defined, so it adds nothing.
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.core.model.kernels import TWO_PI


@numba.njit(cache=True, inline="always")
def sparse_kernel_slope(r: float) -> float:  # pragma: no cover - compiled
    """dk_SP/dr at one radius; 0 for r >= 1."""
    if r >= 1.0:
        return 0.0
    return (2.0 * np.cos(TWO_PI * r) - 2.0) / 3.0 - TWO_PI * np.sin(TWO_PI * r) * (1.0 - r) / 3.0


def sparse_kernel_slope_reference(r: np.ndarray) -> np.ndarray:
    """Plain NumPy dk_SP/dr for an array of radii."""
    r = np.asarray(r, dtype=np.float64)
    inside = (2.0 * np.cos(TWO_PI * r) - 2.0) / 3.0 - TWO_PI * np.sin(TWO_PI * r) * (1.0 - r) / 3.0
    return np.where(r < 1.0, inside, 0.0)


@numba.njit(cache=True, parallel=True)
def logit_gradients(
    points, indptr, rows, means, transforms, planar, weights
):  # pragma: no cover - compiled
    """(n, d) float64 gradient of w^T phi(x), 1/m, at each of (n, d) points, metres, over the
    clusters rows[indptr[i]:indptr[i + 1]] of point i."""
    n, d = points.shape
    out = np.zeros((n, d))
    for i in numba.prange(n):
        u = np.empty(d)
        for e in range(indptr[i], indptr[i + 1]):
            m = rows[e]
            if planar[m]:
                continue
            r2 = 0.0
            for a in range(d):
                value = 0.0
                for b in range(d):
                    value += transforms[m, a, b] * (points[i, b] - means[m, b])
                u[a] = value
                r2 += value * value
            r = np.sqrt(r2)
            if r == 0.0 or r >= 1.0:
                continue
            scale = weights[m] * sparse_kernel_slope(r) / r
            for b in range(d):
                g = 0.0
                for a in range(d):
                    g += transforms[m, a, b] * u[a]
                out[i, b] += scale * g
    return out


def logit_gradients_reference(
    points: np.ndarray,
    indptr: np.ndarray,
    rows: np.ndarray,
    means: np.ndarray,
    transforms: np.ndarray,
    planar: np.ndarray,
    weights: np.ndarray,
) -> np.ndarray:
    """Plain NumPy twin of `logit_gradients`."""
    point_of_entry = np.repeat(np.arange(len(points)), np.diff(indptr))
    offsets = points[point_of_entry] - means[rows]
    u = np.einsum("eab,eb->ea", transforms[rows], offsets)
    r = np.linalg.norm(u, axis=1)
    active = ~planar[rows] & (r > 0.0) & (r < 1.0)
    scale = np.where(
        active, weights[rows] * sparse_kernel_slope_reference(r) / np.where(r > 0, r, 1.0), 0.0
    )
    entries = scale[:, None] * np.einsum("eab,ea->eb", transforms[rows], u)
    out = np.zeros(points.shape)
    np.add.at(out, point_of_entry, entries)
    return out
