import numpy as np

from ehm.features import (
    decision_values,
    decision_values_reference,
    kernel_values,
    kernel_values_reference,
)
from ehm.kernels import kernel_transforms, sparse_kernel, sparse_kernel_reference


def test_sparse_kernel_matches_reference_and_known_values():
    radii = np.linspace(0.0, 1.5, 301)
    compiled = np.array([sparse_kernel(r) for r in radii])
    np.testing.assert_allclose(compiled, sparse_kernel_reference(radii), atol=1e-15)
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


def _random_problem(rng, dim):
    n_clusters, n_points, n_groups, k = 40, 500, 30, 6
    means = rng.uniform(0, 2, (n_clusters, dim))
    a = rng.normal(size=(n_clusters, dim, dim)) * 0.2
    covariances = a @ np.swapaxes(a, 1, 2)
    transforms = kernel_transforms(covariances, 3.0, 0.05)
    points = rng.uniform(0, 2, (n_points, dim))
    group_of_point = rng.integers(0, n_groups, n_points)
    neighbours = rng.integers(0, n_clusters, (n_groups, k))
    neighbours[0, 3:] = -1  # fewer clusters than k
    return points, group_of_point, neighbours, means, transforms


def test_kernel_values_match_reference(rng):
    for dim in (2, 3):
        problem = _random_problem(rng, dim)
        compiled = kernel_values(*problem)
        np.testing.assert_allclose(compiled, kernel_values_reference(*problem), atol=1e-12)
        assert np.count_nonzero(compiled) > 0.1 * compiled.size


def test_decision_values_match_reference(rng):
    problem = _random_problem(rng, 3)
    weights = rng.normal(size=len(problem[3]))
    compiled = decision_values(*problem, weights, 0.3)
    np.testing.assert_allclose(
        compiled, decision_values_reference(*problem, weights, 0.3), atol=1e-12
    )
