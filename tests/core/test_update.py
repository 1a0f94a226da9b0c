"""One update (Alg. 2) of a learned model, step by step."""

import numpy as np

from ehm.config import MapConfig
from ehm.core.learned_model import LearnedModel
from ehm.core.observations.evidence import gather_evidence
from ehm.core.observations.samples import TrainingSamples, scan_rays
from ehm.core.timing import StageTimer
from ehm.core.update import REPLAY_CELL_RADII, replay_groups, update

STAGES = [
    "memory_lookup",
    "forgetting",
    "clustering",
    "merging",
    "index",
    "replay",
    "features",
    "sgd",
    "precision",
    "memory_insert",
]


def _halves(scan):
    """The scan's even and odd rays: the same surfaces seen twice."""
    every = np.arange(len(scan))
    return [scan.subset(every % 2 == 0)], [scan.subset(every % 2 == 1)]


def _learn(model, scans, time=None):
    rays = scan_rays(scans, model.config)
    samples = gather_evidence(rays, model.config, model.rng)
    timer = StageTimer()
    return update(model, rays, samples, time, timer), timer, samples


def test_an_update_learns_a_scan_into_an_empty_model(room):
    model = LearnedModel.empty(MapConfig(), 3)
    report, timer, samples = _learn(model, room.scans[:1])
    assert list(timer.seconds) == STAGES
    assert report["new_clusters"] == len(model.clusters) > 100
    assert report["merged_clusters"] == 0 and report["replayed_samples"] == 0
    assert report["new_samples"] == len(samples) and len(model.memory) > 0
    scan = room.scans[0]
    hits = scan.points_world[scan.hit_mask]
    halfway = (scan.origin + hits) / 2.0
    assert np.mean(model.log_odds(hits, "batch", False)[0] > 0.0) > 0.9
    assert np.mean(model.log_odds(halfway, "batch", False)[0] < 0.0) > 0.9


def test_a_second_scan_merges_into_the_clusters_and_replays_the_memory(room):
    model = LearnedModel.empty(MapConfig(), 3)
    first, second = _halves(room.scans[0])
    _learn(model, first)
    before = len(model.clusters)
    report, _, _ = _learn(model, second)
    assert report["merged_clusters"] > report["new_clusters"]
    assert len(model.clusters) == before + report["new_clusters"]
    assert report["replayed_samples"] > 0


def test_clustering_does_not_depend_on_the_kernel_search(room):
    first = [LearnedModel.empty(MapConfig(features=f), 3) for f in ("nearest", "support")]
    for model in first:
        _learn(model, room.scans[:1])
    np.testing.assert_array_equal(first[0].clusters.means, first[1].clusters.means)
    assert not np.array_equal(first[0].clusters.weights, first[1].clusters.weights)


def test_time_stamps_keep_the_latest(room):
    model = LearnedModel.empty(MapConfig(forget_after=10.0), 3)
    first, second = _halves(room.scans[0])
    _learn(model, first, time=5.0)
    assert model.time == 5.0 and np.all(model.clusters.seen == 5.0)
    report, _, _ = _learn(model, second, time=3.0)
    assert model.time == 5.0 and report["faded_clusters"] == 0


def test_replayed_samples_share_searches_in_cells_by_kind(rng):
    config = MapConfig()
    kinds = rng.integers(0, 3, 3000)  # occupied, free around hits, free along rays
    # Around hits within 0.6 m, along rays within 6 m: a few samples to each cell.
    points = rng.uniform(0.0, 1.0, (3000, 3)) * np.where(kinds == 2, 6.0, 0.6)[:, None]
    replayed = TrainingSamples(points, kinds == 0, kinds < 2)
    groups = replay_groups(replayed, config)
    along_rays = kinds == 2
    for group in range(len(groups.centres)):
        members = groups.group_of_point == group
        assert len(set(along_rays[members])) == 1  # one kind of search per group
        radius = config.free_cluster_radius if along_rays[members][0] else config.cluster_radius
        cell = REPLAY_CELL_RADII * radius
        assert np.ptp(points[members], axis=0).max() < cell
        np.testing.assert_allclose(groups.centres[group], points[members].mean(axis=0))
    assert len(groups.centres) < 0.2 * len(points)
    assert len(replay_groups(replayed.subset(np.zeros(0, dtype=int)), config).centres) == 0
