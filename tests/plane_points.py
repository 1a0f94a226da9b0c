"""Points on planes for the tests of plane fits, and how to compare the normals found."""

import numpy as np


def planar_patches(
    rng: np.random.Generator, dim: int, patches: int, size: int, spread: float, noise: float
) -> np.ndarray:
    """(patches * size, dim): `patches` patches of planes (lines in 2D) of random orientations
    centred in [-2, 2]^dim, `size` points each, Gaussian `spread` metres along the plane and
    `noise` metres across it."""
    centres = rng.uniform(-2.0, 2.0, (patches, dim))
    normals = rng.normal(size=(patches, dim))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    along = rng.normal(size=(patches, size, dim)) * spread
    along -= np.einsum("pnd,pd->pn", along, normals)[..., None] * normals[:, None, :]
    across = rng.normal(size=(patches, size, 1)) * noise * normals[:, None]
    return (centres[:, None, :] + along + across).reshape(-1, dim)


def assert_same_normals(compiled: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Assert that two (n, d) arrays of normals are NaN at the same rows and agree elsewhere,
    each up to its sign; returns the (n,) bool rows that have one."""
    np.testing.assert_array_equal(np.isnan(compiled), np.isnan(reference))
    planar = ~np.isnan(reference[:, 0])
    signs = np.sign(np.sum(compiled[planar] * reference[planar], axis=1))
    np.testing.assert_allclose(compiled[planar] * signs[:, None], reference[planar], atol=1e-7)
    return planar
