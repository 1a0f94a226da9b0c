"""The map's clusters: rows appended, removed and refreshed, and the copy users see."""

import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import STORED_AS, ClusterSet, ClusterView
from ehm.core.model.kernels import kernel_transforms


def three_clusters() -> ClusterSet:
    clusters = ClusterSet.empty(3)
    covariances = np.array([np.diag([0.04, 0.04, 1e-6]), np.eye(3) * 0.01, np.eye(3) * 0.09])
    clusters.append(
        np.arange(9.0).reshape(3, 3),
        covariances,
        np.array([10, 20, 30]),
        np.array([False, False, True]),
        np.array([True, False, False]),
    )
    return clusters


def test_appended_clusters_start_at_weight_zero_and_get_their_kernels_on_refresh():
    clusters = three_clusters()
    assert len(clusters) == 3 and clusters.dim == 3
    np.testing.assert_array_equal(clusters.weights, 0.0)
    np.testing.assert_array_equal(clusters.grad_sq, 0.0)
    np.testing.assert_array_equal(clusters.transforms, 0.0)
    config = MapConfig(planar_kernel=True)
    clusters.refresh(np.arange(3), config)
    np.testing.assert_array_equal(clusters.planar, [True, False, False])
    np.testing.assert_array_equal(clusters.planar_kernel, [True, False, False])
    expected = kernel_transforms(clusters.covariances, 3.0, 0.02, clusters.planar_kernel)
    # Computed in 64 bits, kept in 32 (STORED_AS); means and weights in 64.
    assert {clusters.arrays()[name].dtype for name in STORED_AS} == {np.dtype(np.float32)}
    assert clusters.means.dtype == clusters.weights.dtype == np.float64
    np.testing.assert_array_equal(clusters.transforms, expected.astype(np.float32))
    # Reach: 3 standard deviations (0.1 and 0.3 m) for k_SP.
    np.testing.assert_allclose(clusters.reach()[1:], [0.3, 0.9])
    assert clusters.nbytes == sum(a.nbytes for a in clusters.arrays().values())


def test_occupied_kernels_span_their_own_length_scale():
    clusters = three_clusters()  # the first occupied (std 0.2 m in-plane), the others free
    config = MapConfig(length_scale=2.5, occupied_length_scale=4.5)
    clusters.refresh(np.arange(3), config)
    np.testing.assert_allclose(clusters.reach(), [4.5 * 0.2, 2.5 * 0.1, 2.5 * 0.3])
    np.testing.assert_array_equal(clusters.length_scales(np.array([2, 0]), config), [2.5, 4.5])


def test_removal_fills_holes_with_the_last_rows():
    clusters = three_clusters()
    clusters.append(
        np.full((2, 3), 9.0), np.repeat(np.eye(3)[None], 2, 0), np.ones(2), *[np.zeros(2, bool)] * 2
    )
    source = clusters.remove(np.array([0, 2]))
    np.testing.assert_array_equal(source, [3, 1, 4])
    np.testing.assert_array_equal(clusters.counts, [1, 20, 1])


def test_the_users_copy_names_each_cluster():
    clusters = three_clusters()
    clusters.refresh(np.arange(3), MapConfig(planar_kernel=False))
    view = ClusterView.of(clusters)
    assert len(view) == 3
    assert view.kind.tolist() == ["planar", "volumetric", "volumetric"]
    assert view.kernel.tolist() == ["local"] * 3
    assert view.scale.tolist() == ["fine", "fine", "coarse"]
    view.means[0] = -1.0
    assert clusters.means[0, 0] == 0.0  # a copy
