"""The clustering step of Alg. 2: quick-means over each kind of sample."""

import numpy as np

from ehm.config import MapConfig
from ehm.core.clustering import grouping
from ehm.core.clustering.grouping import group_samples
from ehm.core.observations.samples import TrainingSamples, training_samples
from ehm.core.sensor.scan import Scan


def test_samples_of_each_kind_are_clustered_apart(room):
    scan = room.scans[0].subset(np.arange(len(room.scans[0])) % 8 == 0)
    config = MapConfig(cluster_behind_apart=True)
    samples = training_samples(scan, config, np.random.default_rng(0))
    grouped = group_samples(samples, config, np.random.default_rng(0))
    groups, clusters = grouped.groups, grouped.clusters
    # Behind hits, hits, free at surface, free along rays.
    kind = np.where(samples.behind, 4, 2 * samples.occupied + samples.at_surface)
    assert samples.behind.sum() == (samples.occupied & ~samples.behind).sum() > 0
    # No group mixes kinds of sample, and coarse groups hold the free samples along rays.
    for group in np.unique(groups.group_of_point):
        assert len(np.unique(kind[groups.group_of_point == group])) == 1
    # A sample lies within the inner radius of its group's seed, and the group's centre (the
    # mean of the samples within the outer radius) within the outer radius of it.
    distance = np.linalg.norm(samples.points - groups.centres[groups.group_of_point], axis=1)
    along_rays = ~samples.at_surface
    reach = 1.0 + config.outer_radius_factor
    assert distance[~along_rays].max() < config.cluster_radius * reach
    assert distance[along_rays].max() < config.free_cluster_radius * reach
    # Clusters proper: fine ones for surfaces, coarse ones for free space, labelled by kind.
    assert len(clusters) < len(groups.centres)
    assert clusters.coarse.any() and (~clusters.coarse).any()
    assert not clusters.occupied[clusters.coarse].any()
    # Hits and the samples behind them each need half the least weight of hits.
    assert np.all(clusters.counts[~clusters.occupied] >= config.min_cluster_size)
    assert np.all(clusters.counts[clusters.occupied] >= config.min_hit_cluster_size / 2)
    assert clusters.counts[clusters.occupied].min() < config.min_hit_cluster_size


def test_a_walls_kernels_lie_on_it_with_the_solid_behind_apart():
    """A wall at x = 3 m seen head-on: clustered apart, the hits' clusters are as thin as the
    wall along its normal and those of the samples behind it lie behind it; clustered
    together, each cluster is centred behind the wall and as thick as the samples behind."""
    angles = np.linspace(-0.5, 0.5, 2000)
    ends = np.column_stack([np.full_like(angles, 3.0), 3.0 * np.tan(angles)])
    scan = Scan(ends, np.zeros(2))
    spreads = {}
    for apart in (True, False):
        config = MapConfig(cluster_behind_apart=apart)
        samples = training_samples(scan, config, np.random.default_rng(0))
        clusters = group_samples(samples, config, np.random.default_rng(0)).clusters
        wall = clusters.occupied & (clusters.means[:, 0] < 3.0 + 1e-9)
        behind = clusters.occupied & ~wall
        spreads[apart] = np.sqrt(clusters.covariances[clusters.occupied, 0, 0])
        if apart:
            np.testing.assert_allclose(clusters.means[wall, 0], 3.0, atol=1e-9)
            assert spreads[apart][wall[clusters.occupied]].max() < 1e-6
            depth = clusters.means[behind, 0] - 3.0  # uniform up to occupied_depth: half of it
            assert 0.4 * config.occupied_depth < np.median(depth) < 0.6 * config.occupied_depth
        else:
            depth = clusters.means[clusters.occupied, 0] - 3.0
            assert np.median(depth) > 0.2 * config.occupied_depth
            # Half of the samples at the wall, half uniform up to occupied_depth behind it.
            d = config.occupied_depth
            mixture = np.sqrt(0.5 * d**2 / 3 - (d / 4) ** 2)
            assert np.median(spreads[apart]) > 0.7 * mixture


def test_samples_clustered_together_take_the_majority_label():
    # Two occupied and one free sample at one spot, one free sample far away.
    points = np.array([[0.0, 0.0], [0.01, 0.0], [0.0, 0.01], [5.0, 5.0]])
    samples = TrainingSamples(points, np.array([True, True, False, False]), np.ones(4, bool))
    config = MapConfig(cluster_free_apart=False, min_cluster_size=1)
    grouped = group_samples(samples, config, np.random.default_rng(0))
    near = np.linalg.norm(grouped.clusters.means, axis=1) < 1.0
    np.testing.assert_array_equal(np.sort(near), [False, True])
    assert grouped.clusters.occupied[near].all() and not grouped.clusters.occupied[~near].any()
    group_of_point = grouped.groups.group_of_point
    assert len(set(group_of_point[:3])) == 1 and group_of_point[3] != group_of_point[0]
    assert not grouped.clusters.coarse.any()


def test_samples_know_whether_their_seed_made_a_cluster():
    # Three samples together make a cluster of at least 3; a lone one far away does not.
    points = np.array([[0.0, 0.0], [0.01, 0.0], [0.0, 0.01], [5.0, 5.0]])
    samples = TrainingSamples(points, np.ones(4, bool), np.ones(4, bool))
    grouped = group_samples(samples, MapConfig(min_cluster_size=3), np.random.default_rng(0))
    np.testing.assert_array_equal(grouped.in_cluster, [True, True, True, False])
    assert len(grouped.clusters) == 1 and len(grouped.groups.centres) == 2


def test_kinds_clustered_on_threads_group_as_on_one(room, monkeypatch):
    """Each kind clusters on a thread of its own with its seed order drawn beforehand, so the
    groups and clusters do not depend on the threads."""
    scan = room.scans[0].subset(np.arange(len(room.scans[0])) % 4 == 0)
    samples = training_samples(scan, MapConfig(), np.random.default_rng(0))
    runs = []
    for threads in (1, 2):
        monkeypatch.setattr(grouping.numba, "get_num_threads", lambda n=threads: n)
        runs.append(group_samples(samples, MapConfig(), np.random.default_rng(5)))
    one, two = runs
    np.testing.assert_array_equal(one.groups.group_of_point, two.groups.group_of_point)
    np.testing.assert_array_equal(one.groups.centres, two.groups.centres)
    np.testing.assert_array_equal(one.clusters.covariances, two.clusters.covariances)
    np.testing.assert_array_equal(one.in_cluster, two.in_cluster)
    assert len(one.clusters) > 100


def test_fine_samples_of_a_level_are_clustered_with_its_wider_radius():
    """Hits 0.2 m apart along a wall: at level 0 (radius 0.12 m, outer 0.18 m) each seed
    gathers one and makes no cluster of two; at level 1 (0.24 m, outer 0.36 m) seeds gather
    three. The levels given as all 0 cluster as none given."""
    x = np.arange(0.0, 4.0, 0.2)
    points = np.column_stack([x, np.full_like(x, 3.0)])
    samples = TrainingSamples(points, np.ones(len(x), bool), np.ones(len(x), bool))
    config = MapConfig(min_cluster_size=2)
    flat = group_samples(samples, config, np.random.default_rng(0))
    assert len(flat.clusters) == 0
    zeros = group_samples(samples, config, np.random.default_rng(0), np.zeros(len(x), np.int64))
    np.testing.assert_array_equal(zeros.groups.group_of_point, flat.groups.group_of_point)
    levels = (x >= 2.0).astype(np.int64)  # the far half at level 1
    wide = group_samples(samples, config, np.random.default_rng(0), levels)
    assert len(wide.clusters) > 0
    assert not wide.in_cluster[levels == 0].any() and wide.in_cluster[levels == 1].mean() > 0.5
    assert np.all(wide.clusters.means[:, 0] > 1.9)
    # No group mixes levels, and the wide ones reach as far as their radius allows.
    group_of_point = wide.groups.group_of_point
    for group in np.unique(group_of_point):
        assert len(np.unique(levels[group_of_point == group])) == 1
    spread = np.abs(x - wide.groups.centres[group_of_point, 0])
    assert spread[levels == 1].max() > 0.12


def test_a_lone_hit_makes_a_cluster_with_a_smaller_least_weight_of_hits():
    """Three hits 2 m apart, each with its sample behind (weight 2 within the outer radius),
    and a free sample in front of each: with `min_hit_cluster_size` 4 none makes a cluster; with
    2 (the default) each hit does, and the free samples still make none."""
    hits = np.array([[0.0, 0.0, 5.0], [2.0, 0.0, 5.0], [4.0, 0.0, 5.0]])
    depth = np.array([0.0, 0.0, 0.05])
    behind = hits + depth
    front = hits - depth
    samples = TrainingSamples(
        np.vstack([hits, behind, front]),
        np.repeat([True, True, False], 3),
        np.ones(9, dtype=bool),
    )
    for least, clustered in ((4, 0), (2, 3)):
        config = MapConfig(min_hit_cluster_size=least)
        clusters = group_samples(samples, config, np.random.default_rng(0)).clusters
        assert clusters.occupied.sum() == clustered
        assert not (~clusters.occupied).any()
    with_behind_apart = MapConfig(cluster_behind_apart=True)
    behind_flag = np.repeat([False, True, False], 3)
    apart = TrainingSamples(
        samples.points, samples.occupied, samples.at_surface, None, None, behind_flag
    )
    clusters = group_samples(apart, with_behind_apart, np.random.default_rng(0)).clusters
    assert clusters.occupied.sum() == 6  # each hit and each sample behind: half the weight
