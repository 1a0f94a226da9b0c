"""Anchor layers searched top-down (Sec. 3.4, Fig. 6)."""

import numpy as np

import ehm
from ehm.core.search.anchors import (
    AnchorLayers,
    AnchorTree,
    search_top_down,
    search_top_down_reference,
)
from ehm.core.search.index import ClusterIndex


def anchored(clusters, layers=1, factor=4.0):
    anchors = AnchorLayers()
    anchors.extend(clusters.means, clusters.coarse, (0.12, 0.6), factor, layers)
    return anchors


def test_compiled_top_down_search_matches_reference(rng, random_clusters):
    clusters = random_clusters(rng, 2000, 10.0)
    tree = AnchorTree.build(anchored(clusters, 2, 4.0), clusters.means, clusters.coarse, False)
    assert tree.n_layers == 2 and len(tree.top) > 1
    points = rng.uniform(0, 10, (300, 3))
    args = (points, 6, 2.0**2, tree.centres, tree.child_start, tree.children, tree.top, 2)
    np.testing.assert_array_equal(search_top_down(*args), search_top_down_reference(*args))


def test_every_cluster_has_one_anchor_of_its_scale_within_the_radius(rng, random_clusters):
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


def test_top_down_search_equals_flat_search_in_the_common_case(room, room_map):
    """Fine clusters crowd on surfaces, and anchors hold whole patches of them: near surfaces,
    the fine neighbours found top-down are the flat search's. Coarse clusters lie thinly
    through open space, where the exception below happens at about 4 % of the points."""
    clusters = room_map.clusters_
    points = room.scans[0].points_world[::20]
    points = points + np.random.default_rng(0).normal(0, 0.1, points.shape)
    flat = ClusterIndex.of(clusters).nearest(points, 8, 4)
    for layers in (1, 2):
        index = ClusterIndex(
            clusters.means, clusters.coarse, clusters.reach(), None, anchored(clusters, layers)
        )
        top_down = index.nearest(points, 8, 4)
        same = np.sort(flat, axis=1) == np.sort(top_down, axis=1)
        assert np.all(same[:, :8])
        assert np.all(same, axis=1).mean() > 0.94


def test_top_down_search_misses_neighbours_of_sparse_clusters(rng, random_clusters):
    """The exception: a point's k-th nearest cluster can belong to an anchor whose centre is
    not among the k nearest of its layer. With clusters scattered thinly through space (about
    2 per anchor) this happens at about one point in seven; the clusters found instead are
    still near."""
    clusters = random_clusters(rng, 3000, 10.0)
    points = rng.uniform(0, 10, (2000, 3))
    flat = ClusterIndex.of(clusters).nearest_of_scale(points, False, 8)
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
    before = [len(c) for c in hilbert_map.model_.anchors.coarse]
    hilbert_map.integrate_scan(halves[1])
    after = [len(c) for c in hilbert_map.model_.anchors.coarse]
    assert len(before) == 2 and before[0] > before[1] > 1
    assert after[0] >= before[0] and after[1] >= before[1]
    assert len(hilbert_map.model_.anchors.parents[0]) == hilbert_map.n_clusters
    assert hilbert_map.model_.anchors.parents[0].min() >= 0


def test_top_down_searches_skip_only_points_with_no_centre_near(rng, random_clusters):
    """Clusters in a 10 m box, points in a 40 m one, most far from every centre: asked all
    at once (the index then counts centres near, from the anchor tree's own, and searches
    only the points with some), they find what they find asked a few hundred at a time
    (every point searched)."""
    clusters = random_clusters(rng, 2000, 10.0)
    index = ClusterIndex(
        clusters.means, clusters.coarse, clusters.reach(), None, anchored(clusters)
    )
    points = rng.uniform(-15.0, 25.0, (4000, 3))
    together = index.nearest(points, 8, 4, 0.1)
    apart = np.vstack([index.nearest(part, 8, 4, 0.1) for part in np.array_split(points, 16)])
    np.testing.assert_array_equal(together, apart)
    assert 0.5 < np.mean(np.all(together == -1, axis=1)) < 1.0
    assert index._counts[0] is not None  # the table was made and read
