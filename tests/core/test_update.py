"""One update (Alg. 2) of a learned model, step by step."""

import numpy as np

from ehm.config import MapConfig
from ehm.core.learned_model import LearnedModel
from ehm.core.observations.evidence import gather_evidence
from ehm.core.observations.samples import scan_rays
from ehm.core.timing import StageTimer
from ehm.core.update import update

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
