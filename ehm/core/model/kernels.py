"""The kernels of a cluster: k_SP with localized length-scales (Eq. 8, 10-12) and the
planar-surface kernel k_PS (Eq. 13).

Both act on u = T_m (x - mu_m), where T_m = diag(1 / (s sqrt(lambda'))) V^T comes from the
eigen decomposition Sigma_m = V diag(lambda) V^T, lambda' = max(lambda, min_std^2) (so flat
clusters stay usable) and s is how many standard deviations the kernel spans along each
eigen-axis:
- localized length-scale kernel: k_SP(|u|) with s = length_scale: it fades to 0 on the
  ellipsoid |u| = 1;
- planar-surface kernel: 1 inside the box max_a |u_a| < 1, else 0, with s = 2 (the paper's
  lambda'_k = 2 sqrt(lambda_k): the transition sits two standard deviations out).
Clusters whose smallest eigenvalue is a small share of the next one are planar (walls,
floors; segments of lines in 2D), and their normal is the eigenvector of that eigenvalue.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ehm.core.primitives.eigen import symmetric_eigen

TWO_PI = 2.0 * np.pi
# Standard deviations the planar-surface kernel spans on each side of its mean (Eq. 13).
PLANAR_SPAN = 2.0


def sparse_kernel_reference(r: np.ndarray) -> np.ndarray:
    """Plain NumPy k_SP of Eq. 8 for an array of radii."""
    r = np.asarray(r, dtype=np.float64)
    inside = (2.0 + np.cos(TWO_PI * r)) / 3.0 * (1.0 - r) + np.sin(TWO_PI * r) / TWO_PI
    return np.where(r < 1.0, inside, 0.0)


# k_SP of Eq. 8 vanishes to fifth order at r = 1: with e = 1 - r and t = 2 pi e,
# k_SP = ((2 + cos t) t / 3 - sin t) / (2 pi) = e^5 g(e), g analytic with g(0) = (2 pi)^4 / 180.
# The compiled kernel evaluates e^5 times a polynomial of degree SPARSE_KERNEL_DEGREE through g
# at Chebyshev points: within 3e-15 of Eq. 8 and positive on [0, 1) like it, and faster
# without a sine and a cosine.
SPARSE_KERNEL_DEGREE = 18


def _quotient_series(e: np.ndarray) -> np.ndarray:
    """g(e) = k_SP(1 - e) / e^5, e in [0, 1]: below e = 1/4 from the power series of the sine
    and cosine (the terms of t^(2m+1), m >= 2, of (2 + cos t) t / 3 - sin t, divided by 2 pi
    e^5), where Eq. 8 itself cancels to a few digits; above it from Eq. 8."""
    e = np.asarray(e, dtype=np.float64)
    t = TWO_PI * e
    series = np.zeros_like(t)
    for m in range(30, 1, -1):  # smallest terms first
        coefficient = (-1) ** m * (1 / (3 * math.factorial(2 * m)) - 1 / math.factorial(2 * m + 1))
        series += coefficient * t ** (2 * m - 4)
    with np.errstate(divide="ignore", invalid="ignore"):
        direct = sparse_kernel_reference(1.0 - e) / e**5
    return np.where(e < 0.25, TWO_PI**4 * series, direct)


def _sparse_kernel_coefficients(degree: int) -> np.ndarray:
    """Coefficients, highest power first, of the polynomial in x = 2 e - 1 that interpolates
    g(e) = k_SP(1 - e) / e^5 on e in [0, 1] at Chebyshev points."""
    chebyshev = np.polynomial.chebyshev
    interpolant = chebyshev.chebinterpolate(lambda x: _quotient_series((x + 1.0) / 2.0), degree)
    return chebyshev.cheb2poly(interpolant)[::-1].copy()


_SPARSE_KERNEL_COEFFICIENTS = _sparse_kernel_coefficients(SPARSE_KERNEL_DEGREE)


@numba.njit(cache=True, inline="always")
def sparse_kernel(r: float) -> float:  # pragma: no cover - compiled
    """k_SP(r) of Eq. 8 for one radius, as e^5 g(e), e = 1 - r (to 3e-15); exactly 0 for
    r >= 1, without a branch, so loops of it run in vector registers."""
    e = max(1.0 - r, 0.0)
    x = 2.0 * e - 1.0
    quotient = 0.0
    for coefficient in _SPARSE_KERNEL_COEFFICIENTS:
        quotient = quotient * x + coefficient
    e2 = e * e
    return e2 * e2 * e * quotient


@numba.njit(cache=True, inline="always")
def projected_radii(points, i, cluster, means, transforms):  # pragma: no cover - compiled
    """|u|^2 and max_a |u_a| of u = T_m (x_i - mu_m), m = cluster."""
    d = points.shape[1]
    r2 = 0.0
    r_max = 0.0
    for a in range(d):
        u = 0.0
        for b in range(d):
            u += transforms[cluster, a, b] * (points[i, b] - means[cluster, b])
        r2 += u * u
        r_max = max(r_max, abs(u))
    return r2, r_max


# Kernel codes: the projected radii of many (point, cluster) pairs, written in one pass, that
# kernels_of_codes turns into kernel values in another, where the polynomial of k_SP runs four
# values at a time (several times faster than within the pass that projects). A code is |u|^2
# for k_SP; for k_PS, INSIDE_BOX or OUTSIDE; OUTSIDE also stands for no cluster.
INSIDE_BOX = -1.0
OUTSIDE = 1.0


@numba.njit(cache=True, inline="always")
def kernel_code(r2: float, r_max: float, planar: bool) -> float:  # pragma: no cover
    """The code of a kernel from |u|^2 and max_a |u_a| of u = T_m (x - mu_m)."""
    if planar:
        return INSIDE_BOX if r_max < 1.0 else OUTSIDE
    return r2


@numba.njit(cache=True)
def kernels_of_codes_serial(codes):  # pragma: no cover - compiled
    """kernels_of_codes on one thread: a loop without branches, which LLVM vectorises."""
    for t in range(codes.shape[0]):
        code = codes[t]
        value = sparse_kernel(np.sqrt(max(code, 0.0)))
        codes[t] = 1.0 if code < 0.0 else value


@numba.njit(cache=True, parallel=True)
def kernels_of_codes(codes):  # pragma: no cover - compiled
    """Turn kernel codes (n,) float64 (see kernel_code) into kernel values, in place."""
    n = codes.shape[0]
    parts = 8
    step = (n + parts - 1) // parts
    for part in numba.prange(parts):
        kernels_of_codes_serial(codes[part * step : min(n, (part + 1) * step)])


def cluster_kernel_reference(projected: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """Plain NumPy kernel values of projected (..., d) u, planar (...) bool: k_PS where
    planar, else k_SP (what kernel_code and kernels_of_codes give)."""
    inside_box = np.max(np.abs(projected), axis=-1) < 1.0
    values = sparse_kernel_reference(np.linalg.norm(projected, axis=-1))
    return np.where(planar, inside_box.astype(np.float64), values)


Eigen = tuple[np.ndarray, np.ndarray]
"""An eigen decomposition of (M, d, d) covariances: eigenvalues (M, d) ascending and
eigenvectors (M, d, d) as columns (ehm.core.primitives.eigen.symmetric_eigen)."""


def floored_eigen(
    covariances: np.ndarray, min_std: float, eigen: Eigen | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (M, d), floored at min_std^2, and eigenvectors (M, d, d) as columns; from
    `eigen`, the covariances' decomposition, when it is known."""
    eigenvalues, eigenvectors = symmetric_eigen(covariances) if eigen is None else eigen
    return np.maximum(eigenvalues, min_std**2), eigenvectors


def kernel_transforms(
    covariances: np.ndarray,
    length_scale: float | np.ndarray,
    min_std: float,
    planar: np.ndarray | None = None,
    eigen: Eigen | None = None,
) -> np.ndarray:
    """T_m (M, d, d), 1/m, mapping offsets from the mean to the kernel's unit ball (k_SP,
    `length_scale` standard deviations out: one for all or (M,) one each) or unit box (k_PS,
    rows where `planar`, (M,) bool; None: none); `eigen`: the covariances' decomposition, when
    it is known."""
    eigenvalues, eigenvectors = floored_eigen(covariances, min_std, eigen)
    span = np.broadcast_to(np.asarray(length_scale, dtype=np.float64), len(covariances)).copy()
    if planar is not None:
        span[planar] = PLANAR_SPAN
    scale = 1.0 / (span[:, None] * np.sqrt(eigenvalues))
    return scale[:, :, None] * np.swapaxes(eigenvectors, 1, 2)


def planar_clusters(
    covariances: np.ndarray, ratio: float, eigen: Eigen | None = None
) -> np.ndarray:
    """(M,) bool: clusters whose smallest covariance eigenvalue is at most `ratio` times the
    next smallest (unfloored), so their spread across one axis is small against the others;
    `eigen`: the covariances' decomposition, when it is known."""
    if len(covariances) == 0:
        return np.zeros(0, dtype=bool)
    eigenvalues, _ = symmetric_eigen(covariances) if eigen is None else eigen
    return eigenvalues[:, 0] <= ratio * eigenvalues[:, 1]


def cluster_normals(covariances: np.ndarray) -> np.ndarray:
    """(M, d) unit eigenvectors of the smallest eigenvalue: the normal of planar clusters
    (sign arbitrary)."""
    return symmetric_eigen(covariances)[1][:, :, 0]


def covariance_square_roots(
    covariances: np.ndarray, min_std: float, eigen: Eigen | None = None
) -> np.ndarray:
    """Symmetric square roots (M, d, d), metres, of the floored covariances; `eigen`: their
    decomposition, when it is known."""
    eigenvalues, eigenvectors = floored_eigen(covariances, min_std, eigen)
    halves = eigenvectors * eigenvalues[:, None, :] ** 0.25  # V diag(lambda^1/4)
    return np.matmul(halves, np.swapaxes(halves, 1, 2))


def transform_square_roots(
    transforms: np.ndarray, planar: np.ndarray, length_scale: float | np.ndarray
) -> np.ndarray:
    """The symmetric square roots (M, d, d), metres, of the floored covariances that kernel
    transforms T_m (M, d, d) were made from (kernel_transforms with `length_scale`, one or
    (M,), k_PS where `planar` (M,) bool), read off them without a decomposition: row a of T_m
    is v_a^T / (s sqrt(lambda'_a)), so the root, sum_a sqrt(lambda'_a) v_a v_a^T, is
    sum_a row_a row_a^T / (s |row_a|^3)."""
    span = np.where(planar, PLANAR_SPAN, length_scale)
    norms = np.linalg.norm(transforms, axis=2)
    rows = transforms / np.sqrt(span[:, None] * norms**3)[:, :, None]
    return np.matmul(np.swapaxes(rows, 1, 2), rows)


def kernel_reach(transforms: np.ndarray, planar: np.ndarray | None = None) -> np.ndarray:
    """(M,) metres: the distance from its mean beyond which each cluster's kernel is zero.

    Row a of T_m is (1 / (s sqrt(lambda'_a))) v_a^T, with half-width h_a = 1 / |row a| along
    eigen-axis a. The ball reaches the largest h_a; the box (rows where `planar`) reaches its
    corners, sqrt(sum_a h_a^2)."""
    if len(transforms) == 0:
        return np.zeros(0)
    with np.errstate(divide="ignore"):  # an all-zero transform reaches everywhere
        half_widths = 1.0 / np.linalg.norm(transforms, axis=2)
    reach = half_widths.max(axis=1)
    if planar is not None:
        reach[planar] = np.linalg.norm(half_widths[planar], axis=1)
    return reach


def support_half_widths(transforms: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """(M, d) metres: half-widths of the axis-aligned box around each kernel's support, for
    kernel transforms (M, d, d) 1/m (d 2 or 3, as maps are) and planar (M,) bool.

    The support {mu + T^-1 u} with |u| < 1 (ball) reaches |row a of T^-1| along world axis a;
    with max_b |u_b| < 1 (box, where `planar`) it reaches the sum of |row a of T^-1|. Each
    T^-1 is the adjugate over the determinant, in one compiled pass on both cores (faster than
    batched np.linalg.inv)."""
    transforms = np.ascontiguousarray(transforms, dtype=np.float64)
    return _half_widths(transforms, np.ascontiguousarray(planar, dtype=np.bool_))


@numba.njit(cache=True, parallel=True)
def _half_widths(transforms, planar):  # pragma: no cover - compiled
    """support_half_widths of (M, d, d) transforms, d 2 or 3."""
    m_count, d = transforms.shape[0], transforms.shape[1]
    half = np.empty((m_count, d))
    for m in numba.prange(m_count):
        t = transforms[m]
        inverse = np.empty((d, d))
        if d == 2:
            det = t[0, 0] * t[1, 1] - t[0, 1] * t[1, 0]
            inverse[0, 0], inverse[0, 1] = t[1, 1] / det, -t[0, 1] / det
            inverse[1, 0], inverse[1, 1] = -t[1, 0] / det, t[0, 0] / det
        else:
            for r in range(3):
                for c in range(3):
                    # Cofactor of t[c, r]: the adjugate is the cofactors' transpose.
                    r1, r2 = (c + 1) % 3, (c + 2) % 3
                    c1, c2 = (r + 1) % 3, (r + 2) % 3
                    inverse[r, c] = t[r1, c1] * t[r2, c2] - t[r1, c2] * t[r2, c1]
            det = t[0, 0] * inverse[0, 0] + t[0, 1] * inverse[1, 0] + t[0, 2] * inverse[2, 0]
            for r in range(3):
                for c in range(3):
                    inverse[r, c] /= det
        for a in range(d):
            total = 0.0
            for b in range(d):
                total += abs(inverse[a, b]) if planar[m] else inverse[a, b] * inverse[a, b]
            half[m, a] = total if planar[m] else np.sqrt(total)
    return half


def support_half_widths_reference(transforms: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """Plain NumPy twin of `support_half_widths`."""
    inverse = np.linalg.inv(transforms)
    return np.where(planar[:, None], np.abs(inverse).sum(axis=2), np.linalg.norm(inverse, axis=2))
