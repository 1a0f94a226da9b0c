"""Training samples drawn along rays."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.observations.samples import (
    TrainingSamples,
    samples_of_scans,
    scan_rays,
    training_samples,
)
from ehm.core.sensor.scan import Scan
from ehm.errors import InputError


def test_training_samples_lie_on_rays_with_the_right_labels(rng):
    origin = np.array([0.0, 0.0, 1.0])
    directions = rng.normal(size=(500, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    lengths = rng.uniform(1.0, 5.0, 500)
    hit = rng.random(500) < 0.8
    scan = Scan(origin + directions * lengths[:, None], origin, hit)
    config = MapConfig(free_spacing=0.25, surface_margin=0.05, occupied_depth=0.1)
    samples = training_samples(scan, config, rng)
    offsets = samples.points - origin
    distance = np.linalg.norm(offsets, axis=1)
    # Every sample is on one of the rays.
    cosine = (offsets / distance[:, None]) @ directions.T
    ray = np.argmax(cosine, axis=1)
    np.testing.assert_allclose(cosine[np.arange(len(ray)), ray], 1.0, atol=1e-9)
    depth = distance - lengths[ray]  # > 0 behind the ray's end
    occupied = samples.occupied
    assert np.all(hit[ray[occupied]])
    assert np.all((depth[occupied] >= -1e-9) & (depth[occupied] <= 0.1 + 1e-9))
    free_on_hits = ~occupied & hit[ray]
    assert np.all(depth[free_on_hits] <= -0.05 / 4 + 1e-9)
    # Samples around hits are flagged: all occupied ones, and one free one per hit in the band.
    in_band = ~occupied & samples.at_surface
    assert np.all(samples.at_surface[occupied])
    assert in_band.sum() == hit.sum()
    assert np.all((depth[in_band] >= -0.05 - 1e-9) & (depth[in_band] <= -0.05 / 4 + 1e-9))
    assert not np.any(samples.at_surface & ~hit[ray])
    assert np.all(depth[~occupied & ~hit[ray]] <= 1e-9)
    # Free density follows the setting: samples standing for about length / spacing per ray.
    along = ~occupied & (depth < -0.05 - 1e-9)
    expected = np.sum(np.maximum(lengths - 0.05 * hit, 0) / 0.25)
    assert abs(samples.weight[along].sum() - expected) < 0.1 * expected


def test_a_hits_free_sample_reaches_front_reach_margins_denser_near_the_hit(rng):
    """With front_reach 2, each hit's free sample lies from a quarter of the margin to two
    margins in front of it, two in three within one margin, half in the nearest quarter of
    that band and 13 % in the farthest."""
    origin = np.zeros(3)
    directions = rng.normal(size=(4000, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    scan = Scan(origin + directions * 3.0, origin, np.ones(4000, dtype=bool))
    config = MapConfig(surface_margin=0.05, front_reach=2.0)
    samples = training_samples(scan, config, rng)
    in_band = ~samples.occupied & samples.at_surface
    depth = 3.0 - np.linalg.norm(samples.points[in_band], axis=1)
    assert in_band.sum() == 4000
    assert depth.min() >= 0.05 / 4 - 1e-9 and depth.max() <= 0.1 + 1e-9
    assert abs(np.mean(depth <= 0.05) - np.sqrt(0.75 / 1.75)) < 0.02
    quarters = np.histogram(depth, bins=np.linspace(0.0125, 0.1, 5))[0] / 4000
    np.testing.assert_allclose(quarters[[0, -1]], [0.5, 1 - np.sqrt(1.3125 / 1.75)], atol=0.02)


def test_a_grazing_hits_free_sample_lies_as_far_off_its_plane_as_head_on(rng):
    """A floor seen from 1 m above, its hits 1.1-3 m away (cosines 0.32-0.67 to its normal):
    each hit's free sample lies from a quarter of the margin to one margin above the floor,
    uniformly, as on a ray along the normal. Without front_stretch it lies that far along the
    ray, the cosine times as high. (Hits in the floor's outermost cells, too few for a plane,
    keep their samples along the ray.)"""
    origin = np.array([0.0, 0.0, 1.0])
    radius, angle = rng.uniform(1.1, 3.0, 20_000), rng.uniform(0.0, 2.0 * np.pi, 20_000)
    floor = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros(20_000)])
    scan = Scan(floor, origin, np.ones(20_000, dtype=bool))
    config = MapConfig(surface_margin=0.05)
    planar = ~np.isnan(scan_rays([scan], config).hit_normals[:, 0])
    assert planar.mean() > 0.99
    cosine = 1.0 / np.sqrt(1.0 + radius**2)
    bounds = ((True, 0.0125, 0.05), (False, 0.0125 * cosine.min(), 0.05 * cosine.max()))
    for stretch, lowest, highest in bounds:
        samples = training_samples(scan, config.replace(front_stretch=stretch), rng)
        height = samples.points[~samples.occupied & samples.at_surface, 2]  # one per hit
        assert height[planar].min() >= lowest - 1e-9 and height[planar].max() <= highest + 1e-9
        if stretch:
            assert abs(np.mean(height[planar]) - 0.03125) < 0.001
    assert abs(np.mean(height) - 0.03125 * np.mean(cosine)) < 0.001


def test_free_samples_far_from_hits_are_sparser_and_weigh_more(rng):
    """With free_thinning 2, within FAR_REACH free cluster radii (2 x 0.6 m) of its hit a
    ray's free samples lie a spacing apart, farther two spacings apart, each of weight 2; a ray
    without a hit is far all along. With 1 (the default) all lie a spacing apart."""
    origin = np.zeros(2)
    angles = rng.uniform(0, 2 * np.pi, 400)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    hit = np.arange(400) < 200
    scan = Scan(directions * 8.0, origin, hit)
    config = MapConfig(free_spacing=0.1, free_cluster_radius=0.6, surface_margin=0.05)
    assert np.all(training_samples(scan, config, rng).weight == 1.0)
    samples = training_samples(scan, config.replace(free_thinning=2), rng)
    along = ~samples.at_surface
    distance = np.linalg.norm(samples.points[along], axis=1)
    ray = np.argmax(samples.points[along] @ directions.T, axis=1)
    weight = samples.weight[along]
    near = hit[ray] & (distance > 8.0 - 1.2)
    np.testing.assert_array_equal(weight, np.where(near, 1.0, 2.0))
    # Samples per metre: 10 near hits, 5 elsewhere; weight per metre 10 everywhere.
    assert abs(near.sum() / (200 * (1.2 - 0.05)) - 10) < 0.5
    assert abs((~near & hit[ray]).sum() / (200 * 6.8) - 5) < 0.3
    assert abs((~hit[ray]).sum() / (200 * 8.0) - 5) < 0.3


def test_free_samples_within_the_fine_band_of_their_hit_are_at_the_surface(rng):
    """With fine_free_band 0.5 (of a 0.6 m free cluster radius), the free samples along a ray
    that lie within 0.3 m before its hit are at_surface, clustered as those around hits; the
    others, and all along rays without a hit, are not. The samples themselves do not move."""
    angles = rng.uniform(0, 2 * np.pi, 400)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    hit = np.arange(400) < 200
    scan = Scan(directions * 8.0, np.zeros(2), hit)
    config = MapConfig(free_spacing=0.1, free_cluster_radius=0.6, surface_margin=0.05)
    plain = training_samples(scan, config, np.random.default_rng(4))
    banded = training_samples(scan, config.replace(fine_free_band=0.5), np.random.default_rng(4))
    np.testing.assert_array_equal(banded.points, plain.points)
    np.testing.assert_array_equal(banded.occupied, plain.occupied)
    moved = banded.at_surface & ~plain.at_surface
    assert not banded.occupied[moved].any() and moved.sum() > 200 * 2  # about 2.5 a ray
    along = ~plain.at_surface
    ray = np.argmax(banded.points @ directions.T, axis=1)
    near = hit[ray] & (np.linalg.norm(banded.points, axis=1) > 8.0 - 0.3)
    np.testing.assert_array_equal(moved[along], near[along])


def test_no_return_rays_give_free_samples_only(rng):
    scan = Scan(np.array([[3.0, 0.0], [0.0, 2.0]]), np.zeros(2), np.array([False, False]))
    samples = training_samples(scan, MapConfig(free_spacing=0.1), rng)
    assert not samples.occupied.any()
    assert 45 < samples.weight.sum() < 55  # 5 m of rays, 0.1 m apart


def test_range_limits_drop_short_rays_and_cut_long_ones(rng):
    """Rays under min_range give no sample; rays over max_range end there without a hit."""
    origin = np.zeros(2)
    points = np.array([[0.2, 0.2], [3.0, 0.0], [0.0, 50.0], [0.0, -50.0]])
    hits = np.array([True, True, True, False])
    config = MapConfig(free_spacing=0.1, min_range=0.5, max_range=10.0)
    samples = training_samples(Scan(points, origin, hits), config, rng)
    distance = np.linalg.norm(samples.points, axis=1)
    assert distance.min() > 0.0 and np.all(distance <= 10.0 + 1e-12)
    # The 0.28 m ray is gone; of the others only the 3 m ray keeps its hit.
    on_x = np.abs(samples.points[:, 1]) < 1e-12
    assert not np.any(np.abs(samples.points[:, 0] - samples.points[:, 1]) < 1e-12)
    np.testing.assert_allclose(samples.points[samples.occupied][:1], [[3.0, 0.0]])
    assert np.all(on_x[samples.occupied])
    # The cut rays are free along their first 10 m, standing for about 10 / 0.1 samples each.
    assert not samples.occupied[~on_x].any()
    for sign in (1, -1):
        along = ~on_x & (np.sign(samples.points[:, 1]) == sign)
        assert 70 < samples.weight[along].sum() < 130
    unlimited = training_samples(Scan(points, origin, hits), MapConfig(free_spacing=0.1), rng)
    assert unlimited.occupied.sum() == 2 * 3


def test_free_samples_per_ray_are_bounded(rng):
    """One point a thousand kilometres away adds at most max_free_samples samples; one beyond
    the reach of the cells its plane is looked for in (1.3e8 m at 12 cm) is refused."""
    config = MapConfig(free_spacing=0.1, max_free_samples=50)
    far = Scan(np.array([[1e6, 0.0], [1.0, 0.0]]), np.zeros(2))
    samples = training_samples(far, config, rng)
    assert len(samples) <= 50 + 3 * 2 + 10
    too_far = Scan(np.array([[1e9, 0.0], [1.0, 0.0]]), np.zeros(2))
    with pytest.raises(InputError, match="set max_range"):
        training_samples(too_far, config, rng)


def test_samples_of_scans_are_each_scans_samples_in_order(plan):
    config = MapConfig()
    together = samples_of_scans(plan.scans[:3], config, np.random.default_rng(4))
    rng = np.random.default_rng(4)
    parts = [training_samples(scan, config, rng) for scan in plan.scans[:3]]
    np.testing.assert_array_equal(together.points, np.concatenate([p.points for p in parts]))
    np.testing.assert_array_equal(together.occupied, np.concatenate([p.occupied for p in parts]))
    assert len(together) == sum(len(p) for p in parts)


def test_sample_sets_add_up_in_order(rng):
    first = TrainingSamples(rng.random((3, 2)), np.array([1, 0, 1], bool), np.ones(3, bool))
    second = TrainingSamples(rng.random((2, 2)), np.array([0, 1], bool), np.zeros(2, bool))
    both = first + second
    np.testing.assert_array_equal(both.points, np.vstack([first.points, second.points]))
    np.testing.assert_array_equal(both.occupied, [1, 0, 1, 0, 1])
    np.testing.assert_array_equal(both.at_surface, [1, 1, 1, 0, 0])


def _ray_scan(rng: np.random.Generator, n: int = 4000) -> Scan:
    origin = np.array([0.5, -0.3, 1.0])
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    lengths = rng.uniform(0.5, 8.0, n)
    return Scan(origin + directions * lengths[:, None], origin, rng.random(n) < 0.7)


def test_a_learn_box_keeps_the_samples_a_whole_map_draws_inside_it(rng):
    scan = _ray_scan(rng)
    box = np.array([[1.0, -2.0, 0.0], [4.0, 2.0, 3.0]])
    config = MapConfig(free_spacing=0.05)
    boxed = training_samples(scan, config.replace(learn_box=box.ravel()), rng)
    whole = training_samples(scan, config, rng)
    inside = np.all((whole.points >= box[0]) & (whole.points <= box[1]), axis=1)
    assert np.all((boxed.points >= box[0] - 1e-9) & (boxed.points <= box[1] + 1e-9))
    # The samples of each kind inside the box, as many as the whole map draws there.
    for occupied, at_surface in ((True, True), (False, True), (False, False)):
        in_whole = inside & (whole.occupied == occupied) & (whole.at_surface == at_surface)
        in_boxed = (boxed.occupied == occupied) & (boxed.at_surface == at_surface)
        expected = in_whole.sum()
        assert abs(in_boxed.sum() - expected) <= 4 * np.sqrt(expected) + 2, (occupied, at_surface)


def test_no_learn_box_and_a_box_holding_every_ray_draw_the_same_samples():
    scan = _ray_scan(np.random.default_rng(3))
    config = MapConfig(free_spacing=0.1, max_free_samples=20)
    whole = training_samples(scan, config, np.random.default_rng(7))
    box = (-20.0, -20.0, -20.0, 20.0, 20.0, 20.0)
    boxed = training_samples(scan, config.replace(learn_box=box), np.random.default_rng(7))
    np.testing.assert_allclose(boxed.points, whole.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(boxed.occupied, whole.occupied)


def test_a_learn_box_of_another_dimension_is_refused(rng):
    scan = _ray_scan(rng, 10)
    with pytest.raises(InputError, match="learn_box is a 2D box, the scan is 3D"):
        training_samples(scan, MapConfig(learn_box=(0, 0, 1, 1)), rng)


def test_concatenated_samples_keep_each_parts_scatter_and_zeros_for_parts_without(rng):
    def part(n, scatter):
        points = rng.normal(size=(n, 3))
        spread = rng.normal(size=(n, 3, 3)) if scatter else None
        return TrainingSamples(points, rng.random(n) < 0.5, rng.random(n) < 0.5, None, spread)

    with_scatter, without = part(5, True), part(3, False)
    joined = with_scatter + without
    np.testing.assert_array_equal(
        joined.points, np.concatenate([with_scatter.points, without.points])
    )
    np.testing.assert_array_equal(joined.scatter[:5], with_scatter.scatter)
    np.testing.assert_array_equal(joined.scatter[5:], np.zeros((3, 3, 3)))
    assert (with_scatter + part(0, False)) is with_scatter  # nothing copied
    assert len(part(0, True) + part(0, False)) == 0
