"""Eigen decompositions of small symmetric matrices against np.linalg.eigh."""

import numpy as np
import pytest

from ehm.core.primitives.eigen import symmetric_eigen


def _covariances(rng, n, dim):
    factors = rng.normal(size=(n, dim, dim))
    scales = 10.0 ** rng.uniform(-8, 4, (n, 1, 1))
    covariances = factors @ np.swapaxes(factors, 1, 2) * scales
    flat = factors[:, :, :1] @ np.swapaxes(factors[:, :, :1], 1, 2)  # rank one: a line
    return np.concatenate([covariances, flat, np.zeros((1, dim, dim)), np.eye(dim)[None]])


@pytest.mark.parametrize("dim", [2, 3])
def test_eigen_decomposition_agrees_with_numpy(rng, dim):
    covariances = _covariances(rng, 3000, dim)
    values, vectors = symmetric_eigen(covariances)
    expected = np.linalg.eigvalsh(covariances)
    size = np.linalg.norm(covariances, axis=(1, 2))[:, None]
    assert np.all(np.abs(values - expected) <= 1e-13 * size)
    # Orthonormal columns that rebuild each matrix.
    np.testing.assert_allclose(
        np.einsum("mji,mjk->mik", vectors, vectors),
        np.broadcast_to(np.eye(dim), vectors.shape),
        atol=1e-12,
    )
    rebuilt = np.einsum("mij,mj,mkj->mik", vectors, values, vectors)
    assert np.all(np.abs(rebuilt - covariances) <= 1e-13 * size[:, :, None])
    # Where eigenvalues are apart, the same axes as numpy's, up to sign.
    _, numpy_vectors = np.linalg.eigh(covariances)
    gaps = np.diff(expected, axis=1).min(axis=1) > 1e-6 * size[:, 0]
    alignment = np.abs(np.einsum("mji,mjk->mik", vectors[gaps], numpy_vectors[gaps]))
    np.testing.assert_allclose(alignment, np.broadcast_to(np.eye(dim), alignment.shape), atol=1e-6)


def test_no_matrices_give_empty_arrays():
    values, vectors = symmetric_eigen(np.zeros((0, 3, 3)))
    assert values.shape == (0, 3) and vectors.shape == (0, 3, 3)
