"""The sparse kernel k_SP (Eq. 8) and the localized length-scale transform (Eq. 10-12).

A cluster m with mean mu_m and covariance Sigma_m contributes k_SP(r) with the Mahalanobis
radius r = |T_m (x - mu_m)|, where T_m = diag(1 / (l sqrt(lambda'))) V^T from the eigen
decomposition Sigma_m = V diag(lambda) V^T, lambda' = max(lambda, min_std^2) (so flat clusters
stay usable) and l the length-scale factor: the kernel vanishes at l standard deviations.
"""

from __future__ import annotations

import numba
import numpy as np

TWO_PI = 2.0 * np.pi


@numba.njit(cache=True, inline="always")
def sparse_kernel(r: float) -> float:  # pragma: no cover - compiled
    """k_SP(r) of Eq. 8 for one radius; exactly 0 for r >= 1."""
    if r >= 1.0:
        return 0.0
    return (2.0 + np.cos(TWO_PI * r)) / 3.0 * (1.0 - r) + np.sin(TWO_PI * r) / TWO_PI


def sparse_kernel_reference(r: np.ndarray) -> np.ndarray:
    """Plain NumPy k_SP of Eq. 8 for an array of radii."""
    r = np.asarray(r, dtype=np.float64)
    inside = (2.0 + np.cos(TWO_PI * r)) / 3.0 * (1.0 - r) + np.sin(TWO_PI * r) / TWO_PI
    return np.where(r < 1.0, inside, 0.0)


def floored_eigen(covariances: np.ndarray, min_std: float) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (M, d), floored at min_std^2, and eigenvectors (M, d, d) as columns."""
    eigenvalues, eigenvectors = np.linalg.eigh(covariances)
    return np.maximum(eigenvalues, min_std**2), eigenvectors


def kernel_transforms(covariances: np.ndarray, length_scale: float, min_std: float) -> np.ndarray:
    """T_m (M, d, d), 1/m, so that r = |T_m (x - mu_m)| is the kernel's radius."""
    eigenvalues, eigenvectors = floored_eigen(covariances, min_std)
    scale = 1.0 / (length_scale * np.sqrt(eigenvalues))
    return scale[:, :, None] * np.swapaxes(eigenvectors, 1, 2)


def covariance_square_roots(covariances: np.ndarray, min_std: float) -> np.ndarray:
    """Symmetric square roots (M, d, d), metres, of the floored covariances."""
    eigenvalues, eigenvectors = floored_eigen(covariances, min_std)
    return np.einsum("mij,mj,mkj->mik", eigenvectors, np.sqrt(eigenvalues), eigenvectors)


def kernel_reach(transforms: np.ndarray) -> np.ndarray:
    """(M,) metres: the distance from its mean beyond which each cluster's kernel is zero.

    Row a of T_m is (1 / (l sqrt(lambda'_a))) v_a^T, so the reach is the largest
    l sqrt(lambda'_a) = 1 / (smallest row norm)."""
    if len(transforms) == 0:
        return np.zeros(0)
    with np.errstate(divide="ignore"):  # an all-zero transform reaches everywhere
        return 1.0 / np.linalg.norm(transforms, axis=2).min(axis=1)
