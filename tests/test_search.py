"""Anisotropic neighbour search and anchor layers (Sec. 3.1, 3.4)."""

import numpy as np
import pytest

import ehm
from ehm.anchors import AnchorLayers, AnchorTree, search_top_down, search_top_down_reference
from ehm.clusters import ClusterSet
from ehm.config import MapConfig
from ehm.index import ClusterIndex, KernelRanking, kernel_radii, kernel_radii_reference


def random_clusters(rng, n=400, extent=6.0):
    clusters = ClusterSet.empty(3)
    spread = rng.normal(size=(n, 3, 3)) * rng.uniform(0.02, 0.15, (n, 1, 1))
    clusters.append(
        rng.uniform(0, extent, (n, 3)),
        spread @ np.swapaxes(spread, 1, 2),
        np.full(n, 10),
        rng.random(n) < 0.2,
        rng.random(n) < 0.5,
    )
    clusters.refresh(np.arange(n), MapConfig(planar_kernel=True, planar_ratio=0.3))
    return clusters


def test_kernel_radii_match_reference(rng):
    clusters = random_clusters(rng)
    assert 0 < clusters.planar_kernel.sum() < len(clusters)
    points = rng.uniform(0, 6, (300, 3))
    candidates = rng.integers(-1, len(clusters), (300, 12))
    args = (points, candidates, clusters.means, clusters.transforms, clusters.planar_kernel)
    compiled, reference = kernel_radii(*args), kernel_radii_reference(*args)
    np.testing.assert_allclose(compiled, reference, rtol=1e-12)
    assert np.all(np.isinf(compiled[candidates < 0]))


def test_anisotropic_search_ranks_by_kernel_radius(rng):
    clusters = random_clusters(rng)
    ranking = KernelRanking(clusters.means, clusters.transforms, clusters.planar_kernel, 3)
    index = ClusterIndex(clusters.means, clusters.coarse, None, ranking)
    points = rng.uniform(0, 6, (200, 3))
    found = index.nearest_of_scale(points, False, 5)
    candidates = ClusterIndex(clusters.means, clusters.coarse).nearest_of_scale(points, False, 15)
    radii = kernel_radii_reference(
        points, candidates, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    expected = np.take_along_axis(candidates, np.argsort(radii, axis=1, kind="stable")[:, :5], 1)
    np.testing.assert_array_equal(found, expected)
    radii_found = kernel_radii_reference(
        points, found, clusters.means, clusters.transforms, clusters.planar_kernel
    )
    assert np.all(np.diff(radii_found, axis=1) >= 0)


def anchored(clusters, layers=1, factor=4.0):
    anchors = AnchorLayers()
    anchors.extend(clusters.means, clusters.coarse, (0.12, 0.6), factor, layers)
    return anchors


def test_compiled_top_down_search_matches_reference(rng):
    clusters = random_clusters(rng, 2000, 10.0)
    tree = AnchorTree.build(anchored(clusters, 2, 4.0), clusters.means, clusters.coarse, False)
    assert tree.n_layers == 2 and len(tree.top) > 1
    points = rng.uniform(0, 10, (300, 3))
    args = (points, 6, 2.0**2, tree.centres, tree.child_start, tree.children, tree.top, 2)
    np.testing.assert_array_equal(search_top_down(*args), search_top_down_reference(*args))


def test_every_cluster_has_one_anchor_of_its_scale_within_the_radius(rng):
    clusters = random_clusters(rng, 1000, 10.0)
    anchors = anchored(clusters)
    parents = anchors.parents[0]
    assert parents.min() >= 0 and len(parents) == len(clusters)
    np.testing.assert_array_equal(anchors.coarse[0][parents], clusters.coarse)
    # A member joined an anchor within r_i of its centre at the time, or seeded it.
    centres = anchors.centres(clusters.means)[0]
    offsets = np.linalg.norm(clusters.means - centres[parents], axis=1)
    radius = np.where(clusters.coarse, 0.6 * 8, 0.12 * 8)
    assert np.all(offsets < 2 * radius)


def test_top_down_search_equals_flat_search_in_the_common_case(room):
    """Fine clusters crowd on surfaces, and anchors hold whole patches of them: near surfaces,
    the fine neighbours found top-down are the flat search's. Coarse clusters lie thinly
    through open space, where the exception below happens at about 4 % of the points."""
    clusters = ehm.HilbertMap().fit(room.scans).clusters_
    points = room.scans[0].points_world[::20]
    points = points + np.random.default_rng(0).normal(0, 0.1, points.shape)
    flat = clusters.index().nearest(points, 8, 4)
    for layers in (1, 2):
        index = ClusterIndex(
            clusters.means, clusters.coarse, clusters.reach(), None, anchored(clusters, layers)
        )
        top_down = index.nearest(points, 8, 4)
        same = np.sort(flat, axis=1) == np.sort(top_down, axis=1)
        assert np.all(same[:, :8])
        assert np.all(same, axis=1).mean() > 0.94


def test_top_down_search_misses_neighbours_of_sparse_clusters(rng):
    """The exception: a point's k-th nearest cluster can belong to an anchor whose centre is
    not among the k nearest of its layer. With clusters scattered thinly through space (about
    2 per anchor) this happens at about one point in seven; the clusters found instead are
    still near."""
    clusters = random_clusters(rng, 3000, 10.0)
    points = rng.uniform(0, 10, (2000, 3))
    flat = clusters.index().nearest_of_scale(points, False, 8)
    index = ClusterIndex(clusters.means, clusters.coarse, None, None, anchored(clusters))
    top_down = index.nearest_of_scale(points, False, 8)
    same = np.all(np.sort(flat, axis=1) == np.sort(top_down, axis=1), axis=1)
    assert 0.7 < same.mean() < 0.99
    distance = np.linalg.norm(clusters.means[top_down] - points[:, None], axis=2)
    flat_distance = np.linalg.norm(clusters.means[flat] - points[:, None], axis=2)
    assert np.all(distance[~same].max(axis=1) < 2 * flat_distance[~same].max(axis=1))


def test_new_clusters_join_or_create_anchors_as_scans_arrive(room):
    scan = room.scans[0]
    halves = [scan.subset(np.arange(len(scan)) % 2 == i) for i in (0, 1)]
    hilbert_map = ehm.HilbertMap(anchor_layers=3)
    hilbert_map.integrate_scan(halves[0])
    before = [len(c) for c in hilbert_map.anchors_.coarse]
    hilbert_map.integrate_scan(halves[1])
    after = [len(c) for c in hilbert_map.anchors_.coarse]
    assert len(before) == 2 and before[0] > before[1] > 1
    assert after[0] >= before[0] and after[1] >= before[1]
    assert len(hilbert_map.anchors_.parents[0]) == hilbert_map.n_clusters
    assert hilbert_map.anchors_.parents[0].min() >= 0


@pytest.mark.parametrize(
    "overrides",
    [
        {"planar_kernel": True},
        {"merge_coplanar": True},
        {"anisotropic_search": True},
        {"anchor_layers": 2},
        {
            "planar_kernel": True,
            "merge_coplanar": True,
            "anisotropic_search": True,
            "anchor_layers": 2,
        },
    ],
)
def test_every_switch_maps_the_room_and_survives_a_round_trip(room, overrides, tmp_path):
    low, high = room.scene.box_min.min(axis=0), room.scene.box_max.max(axis=0)
    points = np.random.default_rng(2).uniform(low, high, (20_000, 3))
    scan = room.scans[0]
    hilbert_map = ehm.HilbertMap(**overrides)
    for part in (0, 1):
        hilbert_map.integrate_scan(scan.subset(np.arange(len(scan)) % 2 == part))
    probability = hilbert_map.occupancy(points)
    seen = np.abs(probability - 0.5) > 0.1
    truth = room.scene.occupied(points[seen])
    assert np.mean((probability[seen] > 0.5) == truth) > 0.9
    hilbert_map.save(tmp_path / "room.ehm")
    loaded = ehm.load(tmp_path / "room.ehm")
    np.testing.assert_array_equal(loaded.occupancy(points), probability)


def test_cluster_view_names_walls_and_floors_as_planar(room):
    view = ehm.HilbertMap(planar_kernel=True).fit(room.scans).clusters()
    assert len(view) == len(view.kind) == len(view.weights)
    assert set(view.kind) == {"planar", "volumetric"}
    np.testing.assert_array_equal(view.kernel == "planar", view.kind == "planar")
    # Free-space clusters in front of the floor (z = 0) are flat with vertical normals.
    floor = (view.kind == "planar") & (view.means[:, 2] < 0.05) & (view.scale == "fine")
    normals = np.linalg.eigh(view.covariances[floor])[1][:, :, 0]
    assert floor.sum() > 50 and np.median(np.abs(normals[:, 2])) > 0.95
    with pytest.raises(RuntimeError, match="map is empty"):
        ehm.HilbertMap().clusters()
