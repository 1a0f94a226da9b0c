"""Calibrated log-odds: the scale fitted to samples, the samples it is fitted on, and a map
that reads held-out rays better calibrated than raw."""

import numpy as np
import pytest

import ehm
from ehm.core.learned_model import LearnedModel
from ehm.core.observations.samples import scan_rays
from ehm.core.weights.calibration import (
    CALIBRATION_SAMPLES,
    SCALE_BOUNDS,
    calibration_samples,
    fitted_scale,
)
from ehm.eval.protocol import held_out_rays


def labelled(rng, true_scale, n):
    """Raw log-odds (n,) and labels drawn with p(occupied) = sigmoid(true_scale s)."""
    log_odds = rng.normal(0.0, 1.5, n)
    occupied = rng.random(n) < 1.0 / (1.0 + np.exp(-true_scale * log_odds))
    return log_odds, occupied


@pytest.mark.parametrize("true_scale", [0.5, 1.0, 3.0])
def test_the_fitted_scale_finds_the_one_the_labels_were_drawn_with(rng, true_scale):
    log_odds, occupied = labelled(rng, true_scale, 40_000)
    found = fitted_scale(log_odds, occupied, np.ones(len(log_odds)))
    assert found == pytest.approx(true_scale, rel=0.05)

    # The loss is least there: a little either way costs more.
    def loss(a):
        z = a * log_odds
        return np.sum(np.where(occupied, np.logaddexp(0.0, -z), np.logaddexp(0.0, z)))

    assert loss(found) < min(loss(0.97 * found), loss(1.03 * found))


def test_weights_count_as_repeated_samples(rng):
    log_odds, occupied = labelled(rng, 2.0, 3000)
    twice = np.repeat(np.arange(3000), np.where(np.arange(3000) % 3 == 0, 2, 1))
    weight = np.where(np.arange(3000) % 3 == 0, 2.0, 1.0)
    once = fitted_scale(log_odds, occupied, weight)
    assert once == pytest.approx(
        fitted_scale(log_odds[twice], occupied[twice], np.ones(len(twice)))
    )


def test_nothing_seen_reads_raw_and_all_right_stops_at_the_bound(rng):
    assert fitted_scale(np.zeros(50), rng.random(50) < 0.5, np.ones(50)) == 1.0
    log_odds = rng.normal(0.0, 1.0, 500)
    assert fitted_scale(log_odds, log_odds > 0, np.ones(500)) == SCALE_BOUNDS[1]


def test_samples_are_hits_points_behind_them_and_free_space_along_rays(room):
    config = ehm.MapConfig()
    rays = scan_rays(room.scans[:1], config)
    samples = calibration_samples(rays, config, np.random.default_rng(0))
    assert len(samples) == CALIBRATION_SAMPLES
    assert 0.05 < samples.occupied.mean() < 0.95
    # No free sample in front of a hit (the sampling puts those in the surface's blur).
    assert not samples.at_surface[~samples.occupied].any()
    # Hits among the occupied ones: points where rays of the scan end.
    ends = {tuple(point) for point in np.round(rays.ends[rays.hits], 9)}
    occupied = np.round(samples.points[samples.occupied], 9)
    assert sum(tuple(point) in ends for point in occupied) > 0.3 * len(occupied)


def test_a_calibrated_map_reads_held_out_rays_better_than_raw(plan):
    split = held_out_rays(plan.scans, 0.8, 0.05, 0)
    calibrated = ehm.HilbertMap(calibrate=True).fit(split.train)
    raw = ehm.HilbertMap().fit(split.train)
    scale = calibrated.model_.scale
    assert raw.model_.scale == 1.0 and 1.5 < scale <= SCALE_BOUNDS[1]
    # The same weights, read times the scale: no point changes its side of 0.5.
    np.testing.assert_allclose(
        calibrated.decision_function(split.points), scale * raw.decision_function(split.points)
    )

    def log_loss(p):
        p = np.clip(p, 1e-9, 1.0 - 1e-9)
        return -np.mean(np.where(split.occupied, np.log(p), np.log1p(-p)))

    before, after = (log_loss(m.occupancy(split.points)) for m in (raw, calibrated))
    assert after < 0.8 * before
    free = ~split.occupied
    assert np.mean(calibrated.occupancy(split.points[free]) < 0.196) > np.mean(
        raw.occupancy(split.points[free]) < 0.196
    )


def test_rays_and_distances_at_a_level_read_the_calibrated_occupancy(room):
    """A calibrated map and a raw one learn the same weights; asked at a level, the calibrated
    one answers as the raw one at the level of the same raw log-odds."""
    calibrated = ehm.HilbertMap(calibrate=True).fit(room.scans[:1])
    raw = ehm.HilbertMap().fit(room.scans[:1])
    scale = calibrated.model_.scale
    scan = room.scans[0]
    rng = np.random.default_rng(2)
    ends = scan.points_world[rng.choice(np.flatnonzero(scan.hit_mask), 300, replace=False)]
    directions = (ends - scan.origin) / np.linalg.norm(ends - scan.origin, axis=1)[:, None]
    points = ends + rng.normal(0.0, 0.3, ends.shape)
    for level in (0.3, 0.8):
        raw_level = 1.0 / (1.0 + np.exp(-np.log(level / (1.0 - level)) / scale))
        found = calibrated.raycast(scan.origin, directions, 12.0, level=level)
        np.testing.assert_allclose(found, raw.raycast(scan.origin, directions, 12.0, raw_level))
        assert np.isfinite(found).mean() > 0.95
        np.testing.assert_allclose(
            calibrated.distance(points, level=level), raw.distance(points, level=raw_level)
        )


def test_a_distance_field_kept_at_a_level_follows_a_new_scale(room):
    """The field of a level other than 0.5 stands on the raw log-odds of that level under the
    scale it was made with: an update that moves the scale drops it, and the next query makes
    it at the new raw level; the field of 0.5 (raw level 0) is kept and followed."""
    points = np.random.default_rng(4).uniform([-3.0, -2.0, 0.3], [3.0, 2.0, 2.0], (400, 3))
    scan = room.scans[0]
    rays = np.arange(len(scan))
    first, second = scan.subset(rays % 2 == 0), scan.subset(rays % 2 == 1)
    hilbert_map = ehm.HilbertMap(calibrate=True).integrate_scan(first)
    # The room's fits end at the scale's bound, update after update: start from another.
    assert hilbert_map.model_.scale == SCALE_BOUNDS[1]
    hilbert_map.model_.scale = 3.0
    hilbert_map.distance(points, level=0.8)
    hilbert_map.distance(points, level=0.5)

    def raw_levels():
        return sorted(key[0] for key in hilbert_map._planner._fields)

    logit = np.log(0.8 / 0.2)
    assert raw_levels() == pytest.approx([0.0, logit / 3.0])
    hilbert_map.integrate_scan(second)
    assert raw_levels() == [0.0]
    hilbert_map.distance(points, level=0.8)
    assert raw_levels() == pytest.approx([0.0, logit / hilbert_map.model_.scale])


def test_a_calibrated_map_keeps_its_scale_in_its_file_and_state(plan, tmp_path, rng):
    hilbert_map = ehm.HilbertMap(calibrate=True).fit(plan.scans)
    assert list(hilbert_map.timings_)[-1] == "calibration"
    hilbert_map.save(tmp_path / "plan.ehm")
    loaded = ehm.load(tmp_path / "plan.ehm")
    assert loaded.model_.scale == hilbert_map.model_.scale != 1.0
    points = rng.uniform(-6.0, 6.0, (2000, 2))
    np.testing.assert_array_equal(loaded.occupancy(points), hilbert_map.occupancy(points))
    # The model itself reads raw log-odds; the map reads them times its scale, their variance
    # times its square.
    model = LearnedModel.of_state(hilbert_map.state())
    scores, variance = model.log_odds(points, "batch", True)
    calibrated, spread = hilbert_map.decision_function(points, return_variance=True)
    np.testing.assert_array_equal(model.scale * scores, calibrated)
    np.testing.assert_array_equal(model.scale**2 * variance, spread)


def test_free_samples_in_the_fine_band_are_calibration_samples_too(room):
    """The fine band moves free samples near hits to the fine clusters, not out of the
    calibration: the same draw gives the same samples with and without it."""
    rays = scan_rays(room.scans[:1], ehm.MapConfig())
    plain = calibration_samples(rays, ehm.MapConfig(), np.random.default_rng(1))
    banded = ehm.MapConfig(fine_free_band=0.5)
    again = calibration_samples(rays, banded, np.random.default_rng(1))
    np.testing.assert_array_equal(again.points, plain.points)
    np.testing.assert_array_equal(again.occupied, plain.occupied)
