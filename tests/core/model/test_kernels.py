"""Kernels: k_SP with localized length-scales (Eq. 8, 10-12) and the planar kernel (Eq. 13)."""

import numpy as np
import pytest

from ehm.core.model.kernels import (
    TWO_PI,
    cluster_kernel_reference,
    cluster_normals,
    covariance_square_roots,
    kernel_code,
    kernel_reach,
    kernel_transforms,
    kernels_of_codes_serial,
    planar_clusters,
    sparse_kernel,
    sparse_kernel_reference,
    support_half_widths,
    support_half_widths_reference,
    transform_square_roots,
)


def compiled_kernel(projected: np.ndarray, planar: bool) -> float:
    """A kernel's value at u = projected (d,), as the compiled passes find it: its code, then
    the code's value."""
    code = np.array(
        [kernel_code(float(np.sum(projected**2)), float(np.max(np.abs(projected))), planar)]
    )
    kernels_of_codes_serial(code)
    return float(code[0])


def test_sparse_kernel_matches_reference_and_known_values():
    radii = np.concatenate([np.linspace(0.0, 1.5, 3001), [1.0 - 1e-12, 1.0, 1.0 + 1e-12]])
    compiled = np.array([sparse_kernel(r) for r in radii])
    # The compiled kernel is a polynomial through Eq. 8 at Chebyshev points.
    np.testing.assert_allclose(compiled, sparse_kernel_reference(radii), rtol=0, atol=5e-15)
    assert np.all(compiled[radii >= 1.0] == 0.0)
    # Near r = 1 Eq. 8 vanishes as (1 - r)^5 (2 pi)^4 / 180, which it cancels to nothing in
    # floating point; the compiled kernel keeps it, positive.
    for gap in (1e-2, 1e-3, 1e-5):
        np.testing.assert_allclose(sparse_kernel(1.0 - gap), gap**5 * TWO_PI**4 / 180, rtol=2e-3)
    assert sparse_kernel_reference(np.array([0.0]))[0] == 1.0
    assert np.all(sparse_kernel_reference(np.array([1.0, 1.2])) == 0.0)
    # Eq. 8 at r = 0.5: (2 + cos(pi)) / 3 * 0.5 + sin(pi) / (2 pi) = 1/6
    np.testing.assert_allclose(sparse_kernel_reference(np.array([0.5])), [1.0 / 6.0])


def test_kernel_transform_gives_mahalanobis_radius(rng):
    a = rng.normal(size=(3, 3))
    covariance = a @ a.T + 0.1 * np.eye(3)
    transform = kernel_transforms(covariance[None], length_scale=2.0, min_std=1e-6)[0]
    offset = rng.normal(size=3)
    expected = np.sqrt(offset @ np.linalg.inv(4.0 * covariance) @ offset)
    np.testing.assert_allclose(np.linalg.norm(transform @ offset), expected)


def test_eigenvalue_floor_keeps_flat_clusters_usable():
    flat = np.diag([0.04, 0.04, 0.0])
    transform = kernel_transforms(flat[None], length_scale=1.0, min_std=0.05)[0]
    assert np.all(np.isfinite(transform))
    # Along the flat axis the radius grows as if the standard deviation were 0.05 m.
    np.testing.assert_allclose(np.linalg.norm(transform @ [0, 0, 0.05]), 1.0)


def test_planar_kernel_is_one_within_two_standard_deviations_of_each_axis():
    # A wall in the x-z plane: standard deviations 0.5 (x), 0.01 (y, floored to 0.02), 1 (z).
    covariance = np.diag([0.25, 1e-4, 1.0])
    transform = kernel_transforms(covariance[None], 3.0, 0.02, np.array([True]))[0]
    offsets = np.array(
        [[0.99, 0.0, 0.0], [1.01, 0, 0], [0.9, 0.039, 1.9], [0, 0.041, 0], [0, 0, 2.01]]
    )
    projected = offsets @ transform.T
    values = cluster_kernel_reference(projected, np.ones(5, bool))
    np.testing.assert_array_equal(values, [1, 0, 1, 0, 0])
    compiled = [compiled_kernel(u, True) for u in projected]
    np.testing.assert_array_equal(compiled, values)
    # Corners of the box: sqrt(1^2 + 0.04^2 + 2^2) metres from the mean.
    reach = kernel_reach(transform[None], np.array([True]))
    np.testing.assert_allclose(reach, [np.sqrt(1 + 0.04**2 + 4)])


def test_kernel_is_k_sp_of_the_radius_where_not_planar(rng):
    projected = rng.uniform(-1, 1, (200, 3))
    compiled = [compiled_kernel(u, False) for u in projected]
    expected = sparse_kernel_reference(np.linalg.norm(projected, axis=1))
    np.testing.assert_allclose(compiled, expected, atol=1e-15)
    np.testing.assert_allclose(cluster_kernel_reference(projected, np.zeros(200, bool)), expected)


def test_planar_clusters_and_normals(rng):
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    shapes = np.array([[1.0, 1.0, 0.05], [1.0, 1.0, 0.15], [1.0, 0.05, 0.05], [1, 1, 1]]) ** 2
    covariances = np.einsum("ij,nj,kj->nik", rotation, shapes, rotation)
    # Variance ratios of the smallest to the next: 0.0025, 0.0225, 1 (a line), 1.
    np.testing.assert_array_equal(planar_clusters(covariances, 0.01), [True, False, False, False])
    np.testing.assert_array_equal(planar_clusters(covariances, 0.1), [True, True, False, False])
    normals = cluster_normals(covariances[:2])
    np.testing.assert_allclose(np.abs(normals @ rotation[:, 2]), [1.0, 1.0])


def test_square_roots_read_off_transforms_equal_the_decomposed_ones(rng):
    for dim in (2, 3):
        a = rng.normal(size=(200, dim, dim)) * rng.uniform(0.001, 0.3, (200, 1, 1))
        covariances = a @ np.swapaxes(a, 1, 2)
        planar = rng.random(200) < 0.5
        spans = rng.choice([3.0, 4.5], 200)  # one per kernel, as occupied and free differ
        transforms = kernel_transforms(covariances, spans, 0.02, planar)
        roots = transform_square_roots(transforms, planar, spans)
        np.testing.assert_allclose(roots, covariance_square_roots(covariances, 0.02), atol=1e-12)
        floored = np.linalg.eigvalsh(covariances).min(axis=1) < 0.02**2
        assert 0 < floored.sum() < 200  # some eigenvalues floored, some not
        squares = roots[~floored] @ roots[~floored]
        np.testing.assert_allclose(squares, covariances[~floored], atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_support_half_widths_agree_with_their_twin(rng, dim):
    """The compiled adjugate inverse gives the half-widths np.linalg.inv gives, balls and
    boxes alike."""
    spread = rng.normal(size=(500, dim, dim))
    transforms = spread @ spread.transpose(0, 2, 1) + 0.5 * np.eye(dim)
    planar = rng.random(500) < 0.4
    np.testing.assert_allclose(
        support_half_widths(transforms, planar),
        support_half_widths_reference(transforms, planar),
        rtol=1e-10,
    )
    # A kernel reaching 10 cm along x and 1 m along the other axes (a ball or a box alike).
    narrow = np.diag([10.0, 1.0, 1.0][:dim])[None]
    for kind in (False, True):
        np.testing.assert_allclose(
            support_half_widths(narrow, np.array([kind]))[0], [0.1, 1.0, 1.0][:dim]
        )
