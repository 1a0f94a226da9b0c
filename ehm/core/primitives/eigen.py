"""Eigen decompositions of many small symmetric matrices (cluster covariances, 2x2 or 3x3) in
one compiled pass on every thread: cyclic Jacobi rotations, to machine precision.
np.linalg.eigh is its reference, and pays a LAPACK call per matrix, several times slower on
many small ones.
"""

from __future__ import annotations

import numba
import numpy as np

# Sweeps of rotations before giving up; 3x3 matrices converge in 4-6.
MAX_SWEEPS = 50
# Off-diagonal mass, relative to the whole matrix's, left when a matrix counts as diagonal.
RELATIVE_OFF_DIAGONAL = 1e-32
# Matrices per parallel task.
CHUNK = 256


def symmetric_eigen(matrices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (M, d), ascending, and unit eigenvectors (M, d, d) as columns, of symmetric
    matrices (M, d, d), as np.linalg.eigh gives them (each eigenvector up to its sign)."""
    matrices = np.ascontiguousarray(matrices, dtype=np.float64)
    return _jacobi(matrices)


@numba.njit(cache=True, parallel=True)
def _jacobi(matrices):  # pragma: no cover - compiled
    """symmetric_eigen of (M, d, d) C-contiguous float64 matrices, CHUNK of them a task."""
    m_count, d, _ = matrices.shape
    values = np.empty((m_count, d))
    vectors = np.zeros((m_count, d, d))
    for chunk in numba.prange((m_count + CHUNK - 1) // CHUNK):
        a = np.empty((d, d))
        for m in range(chunk * CHUNK, min((chunk + 1) * CHUNK, m_count)):
            a[:] = matrices[m]
            eigen_in_place(a, values[m], vectors[m])
    return values, vectors


@numba.njit(cache=True, inline="always")
def eigen_in_place(a, values, vectors):  # pragma: no cover - compiled
    """For compiled callers: the eigenvalues of the symmetric (d, d) `a` (overwritten) into
    values (d,), ascending, and its unit eigenvectors as the columns of vectors (d, d), zeros
    on entry."""
    _diagonalise(a, vectors)
    for i in range(a.shape[0]):
        values[i] = a[i, i]
    _sort_ascending(values, vectors)


@numba.njit(cache=True, inline="always")
def _diagonalise(a, v):  # pragma: no cover - compiled
    """Rotate the symmetric (d, d) `a` in place until it is diagonal, its eigenvalues on the
    diagonal; v (d, d), zeros on entry, receives the eigenvectors as columns."""
    d = a.shape[0]
    for i in range(d):
        v[i, i] = 1.0
    total = 0.0
    for i in range(d):
        for j in range(d):
            total += a[i, j] * a[i, j]
    for _ in range(MAX_SWEEPS):
        off = 0.0
        for p in range(d - 1):
            for q in range(p + 1, d):
                off += a[p, q] * a[p, q]
        if off <= RELATIVE_OFF_DIAGONAL * total:
            return
        for p in range(d - 1):
            for q in range(p + 1, d):
                _rotate(a, v, p, q)


@numba.njit(cache=True, inline="always")
def _rotate(a, v, p, q):  # pragma: no cover - compiled
    """Zero a[p, q] (and a[q, p]) by a Jacobi rotation J: a <- J^T a J, v <- v J."""
    apq = a[p, q]
    if apq == 0.0:
        return
    theta = (a[q, q] - a[p, p]) / (2.0 * apq)
    if abs(theta) > 1e150:  # theta^2 would overflow; t ~ 1 / (2 theta)
        t = 0.5 / theta
    else:
        t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
        if theta < 0.0:
            t = -t
    c = 1.0 / np.sqrt(t * t + 1.0)
    s = t * c
    d = a.shape[0]
    for k in range(d):
        akp, akq = a[k, p], a[k, q]
        a[k, p] = c * akp - s * akq
        a[k, q] = s * akp + c * akq
    for k in range(d):
        apk, aqk = a[p, k], a[q, k]
        a[p, k] = c * apk - s * aqk
        a[q, k] = s * apk + c * aqk
    for k in range(d):
        vkp, vkq = v[k, p], v[k, q]
        v[k, p] = c * vkp - s * vkq
        v[k, q] = s * vkp + c * vkq


@numba.njit(cache=True, inline="always")
def _sort_ascending(values, vectors):  # pragma: no cover - compiled
    """Sort values (d,) ascending, with the columns of vectors (d, d), in place."""
    d = values.shape[0]
    for i in range(1, d):
        j = i
        while j > 0 and values[j - 1] > values[j]:
            values[j - 1], values[j] = values[j], values[j - 1]
            for k in range(d):
                vectors[k, j - 1], vectors[k, j] = vectors[k, j], vectors[k, j - 1]
            j -= 1
