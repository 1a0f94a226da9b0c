"""Evidence gathered per cell and kind: the compiled pass against the samples it stands for."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.observations import evidence
from ehm.core.observations.evidence import evidence_reference, gather_evidence
from ehm.core.observations.samples import (
    front_clearances,
    ray_randoms,
    samples_of_rays,
    scan_rays,
)
from ehm.core.primitives.cells import packed_cell_keys
from ehm.core.sensor.scan import Scan
from ehm.errors import InputError


def _scan(rng, n, dim, hits=0.7, spread=8.0):
    origin = rng.normal(size=dim)
    directions = rng.normal(size=(n, dim))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    ends = origin + directions * rng.uniform(0.5, spread, n)[:, None]
    return Scan(ends, origin, rng.random(n) < hits)


def _sorted(samples):
    flags = (samples.occupied, samples.at_surface, samples.behind)
    return samples.subset(np.lexsort((*np.round(samples.points.T, 9), *flags)))


def _evidence_and_twin(rays, config):
    """The compiled pass's evidence of `rays`, sorted, after asserting that its NumPy twin
    holds the same cells: points, weights, scatter and flags."""
    got = _sorted(gather_evidence(rays, config, np.random.default_rng(5)))
    want = _sorted(
        evidence_reference(rays, ray_randoms(len(rays), np.random.default_rng(5)), config)
    )
    assert len(got) == len(want) > 100
    np.testing.assert_allclose(got.points, want.points, atol=1e-9)
    np.testing.assert_allclose(got.weight, want.weight)
    np.testing.assert_allclose(got.scatter, want.scatter, atol=1e-9)
    for flag in ("occupied", "at_surface", "behind"):
        np.testing.assert_array_equal(getattr(got, flag), getattr(want, flag))
    return got


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("box", [False, True])
@pytest.mark.parametrize(
    "thinning, front_reach, pooling, band, apart",
    [
        (1, 1.0, 1, 0.0, False),
        (3, 2.0, 1, 0.0, True),
        (1, 1.0, 2, 0.5, False),
        (2, 2.0, 3, 0.25, True),
    ],
)
def test_compiled_evidence_matches_reference(
    rng, dim, box, thinning, front_reach, pooling, band, apart
):
    config = MapConfig(
        free_spacing=0.3,
        max_free_samples=12,
        free_thinning=thinning,
        front_reach=front_reach,
        surface_pooling=pooling,
        fine_free_band=band,
        cluster_behind_apart=apart,
    )
    if box:
        config = config.replace(learn_box=(-2.0,) * dim + (3.0,) * dim)
    scans = [_scan(rng, 1500, dim), _scan(rng, 700, dim)]
    got = _evidence_and_twin(scan_rays(scans, config), config)
    assert got.behind.any() == apart


def test_compiled_evidence_matches_reference_where_hits_are_noisy(rng):
    """A depth camera's rays on a wall 3.06 m away (in the middle of a layer of 12 cm cells)
    with 1 cm of range noise: each hit's free sample moves clear of the noise (2 standard
    deviations, about 2 cm), in the compiled pass as in its twin."""
    directions = np.column_stack(
        [np.ones(6000), rng.uniform(-0.4, 0.4, 6000), rng.uniform(-0.3, 0.3, 6000)]
    )
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    ranges = 3.06 / directions[:, 0] + rng.normal(0.0, 0.01, 6000)
    scan = Scan(directions * ranges[:, None], np.zeros(3))
    config = MapConfig()
    rays = scan_rays([scan], config)
    clearance = front_clearances(rays, config)
    assert 0.015 < np.median(clearance) < 0.025
    got = _evidence_and_twin(rays, config)
    # The free samples in front of hits lie about the clearance farther from the wall.
    unclear = gather_evidence(rays, config.replace(noise_clearance=0.0), np.random.default_rng(5))
    in_front = got.at_surface & ~got.occupied
    before = unclear.at_surface & ~unclear.occupied
    moved = np.average(got.points[in_front, 0], weights=got.weight[in_front])
    stayed = np.average(unclear.points[before, 0], weights=unclear.weight[before])
    assert stayed - moved == pytest.approx(np.median(clearance), rel=0.3)


@pytest.mark.parametrize("pooling, apart", [(1, False), (2, False), (1, True), (2, True)])
def test_evidence_keeps_the_number_mean_and_scatter_of_every_kind(rng, pooling, apart):
    """Per kind, the weights add up to those of the samples drawn, and their weighted means
    and scatter are the samples' own, with surface_pooling as without; the samples behind hits
    are a kind of their own where they are clustered apart, hits otherwise."""
    config = MapConfig(surface_pooling=pooling, cluster_behind_apart=apart)
    scan = _scan(rng, 3000, 3, spread=2.0)
    rays = scan_rays([scan], config)
    randoms = ray_randoms(len(rays), np.random.default_rng(2))
    samples = samples_of_rays(rays, randoms, config)
    evidence = gather_evidence(scan_rays([scan], config), config, np.random.default_rng(2))
    assert len(evidence) < 0.7 * len(samples)
    behind = samples.behind & apart
    kinds = [(True, True, False), (False, True, False), (False, False, False)]
    for occupied, at_surface, is_behind in kinds + [(True, True, True)] * apart:
        drawn = samples.subset(
            (samples.occupied == occupied)
            & (samples.at_surface == at_surface)
            & (behind == is_behind)
        )
        cells = evidence.subset(
            (evidence.occupied == occupied)
            & (evidence.at_surface == at_surface)
            & (evidence.behind == is_behind)
        )
        assert cells.weight.sum() == drawn.weight.sum()
        mean = drawn.weight @ drawn.points / drawn.weight.sum()
        np.testing.assert_allclose(cells.weight @ cells.points / cells.weight.sum(), mean)
        offsets = cells.points - mean
        total = cells.scatter.sum(axis=0) + np.einsum("n,ni,nj->ij", cells.weight, offsets, offsets)
        drawn_offsets = drawn.points - mean
        want = np.einsum("n,ni,nj->ij", drawn.weight, drawn_offsets, drawn_offsets)
        np.testing.assert_allclose(total, want)


def test_surface_pooling_gathers_a_walls_samples_around_hits_in_fewer_cells(rng):
    """A depth camera's 4,000 hits on a wall 1 m square, 1.5 m away: pooled in cells twice as
    wide, the samples behind and in front of them fill under a third of the cells they filled
    (a slab's cells shrink with the square of the side), the hits' own cells set aside."""
    ends = np.column_stack([rng.uniform(-0.5, 0.5, (4000, 2)), np.full(4000, 1.5)])
    scan = Scan(ends, np.zeros(3))
    cells = {}
    for pooling in (1, 2):
        config = MapConfig(surface_pooling=pooling)
        samples = gather_evidence(scan_rays([scan], config), config, np.random.default_rng(1))
        cells[pooling] = samples.at_surface.sum()
    hit_cells = len(np.unique(np.floor(ends / (MapConfig().cluster_radius / 4)), axis=0))
    assert cells[2] - hit_cells < 0.35 * (cells[1] - hit_cells)


def test_a_batch_with_more_cells_than_rays_grows_its_table(rng):
    """The table starts at the number of rays: 40 long rays with dense free samples fill it
    many times over, and the pass goes on in larger ones without losing a cell."""
    config = MapConfig(free_spacing=0.02)
    scan = _scan(rng, 40, 3, spread=30.0)
    rays = scan_rays([scan], config)
    got = _sorted(gather_evidence(scan_rays([scan], config), config, np.random.default_rng(1)))
    want = _sorted(
        evidence_reference(rays, ray_randoms(len(rays), np.random.default_rng(1)), config)
    )
    assert len(got) == len(want) > 20 * len(rays)
    np.testing.assert_allclose(got.weight, want.weight)
    np.testing.assert_allclose(got.points, want.points, atol=1e-9)


@pytest.mark.parametrize("dim", [2, 3])
def test_cell_corners_are_read_back_from_the_keys(rng, dim):
    """The low corner of a cell, read from its key, is the one the key was made from: cells of
    each kind's side, on both sides of the origin."""
    points = rng.uniform(-50.0, 50.0, (500, dim))
    kinds = rng.integers(0, 4, len(points))
    kind_sides = np.array([0.2, 0.06, 0.03, 0.06])
    sides = kind_sides[kinds]
    keys = packed_cell_keys(points, sides, kinds, evidence.KIND_BITS)
    corners = np.empty((len(points), dim))
    evidence.cell_corners(keys, kind_sides, (63 - evidence.KIND_BITS) // dim, corners)
    np.testing.assert_array_equal(corners, np.floor(points / sides[:, None]) * sides[:, None])


def test_samples_beyond_the_cells_reach_are_refused_naming_the_cause(rng):
    far = Scan(np.array([[1e9, 0.0, 0.0]]), np.zeros(3))
    with pytest.raises(InputError, match="as rays reach 1000000000 m: set max_range"):
        gather_evidence(scan_rays([far], MapConfig()), MapConfig(), rng)
    gone = Scan(np.array([[1e9 + 5.0, 0.0, 0.0]]), np.array([1e9, 0.0, 0.0]))
    with pytest.raises(InputError, match=r"a sensor pose lies 1000000000 m .* in tiles"):
        gather_evidence(scan_rays([gone], MapConfig()), MapConfig(), rng)


def test_evidence_gathered_in_parts_is_the_same_on_any_number_of_threads(rng, monkeypatch):
    """Gathered in parts of its rays, a batch gives the cells of the samples it stands for (a
    cell met by several parts once), in the same order whatever the threads, so a map does not
    depend on the machine."""
    config = MapConfig(free_spacing=0.3)
    scans = [_scan(rng, 3000, 3)]
    rays = scan_rays(scans, config)
    whole = _sorted(
        evidence_reference(rays, ray_randoms(len(rays), np.random.default_rng(3)), config)
    )
    monkeypatch.setattr(evidence, "PARALLEL_MIN_SAMPLES", 1000)
    monkeypatch.setattr(evidence, "GATHER_PARTS", 3)
    runs = []
    for threads in (1, 2, 3):
        monkeypatch.setattr(evidence.numba, "get_num_threads", lambda n=threads: n)
        runs.append(gather_evidence(scan_rays(scans, config), config, np.random.default_rng(3)))
    for run in runs[1:]:
        np.testing.assert_array_equal(run.points, runs[0].points)
        np.testing.assert_array_equal(run.scatter, runs[0].scatter)
    split = _sorted(runs[0])
    assert len(split) == len(whole) > 1000
    np.testing.assert_allclose(split.points, whole.points, atol=1e-9)
    np.testing.assert_allclose(split.weight, whole.weight)
    np.testing.assert_allclose(split.scatter, whole.scatter, atol=1e-9)
    np.testing.assert_array_equal(split.occupied, whole.occupied)
    np.testing.assert_array_equal(split.at_surface, whole.at_surface)
