"""Rays passing through old occupied evidence: the compiled walk over the memory's regions
against its NumPy twin, and the cases that decide what a pass is."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.observations import passes as passes_module
from ehm.core.observations.evidence import (
    FREE_AT_SURFACE,
    OCCUPIED,
    OCCUPIED_BEHIND,
    samples_of_kinds,
)
from ehm.core.observations.memory import EvidenceMemory
from ehm.core.observations.passes import occupied_passes, occupied_passes_reference
from ehm.core.observations.samples import ScanRays


def memory_of(points: np.ndarray, kinds: np.ndarray) -> EvidenceMemory:
    """A memory of fine cells of 5 cm (regions of 20 cm) holding one entry per point."""
    memory = EvidenceMemory(points.shape[1], True, (0.05, 0.3))
    samples = samples_of_kinds(points, kinds, np.ones(len(points)))
    memory.insert(memory.visit(samples), np.ones(len(points), dtype=bool))
    return memory


def rays_of(
    origins: np.ndarray,
    ends: np.ndarray,
    hits: np.ndarray,
    margin: float,
    ray_spacing: float | np.ndarray = 0.0,
) -> ScanRays:
    """Rays from `origins` to `ends` whose free part stops `margin` before each hit, their
    scans' rays `ray_spacing` radians apart (one for all, or (n,))."""
    offsets = ends - origins
    lengths = np.linalg.norm(offsets, axis=1)
    free_end = np.where(hits, lengths - margin, lengths)
    spacing = np.full(len(lengths), 0.5)
    return ScanRays(
        origins,
        offsets / lengths[:, None],
        lengths,
        hits,
        np.zeros(len(lengths)),
        free_end,
        spacing,
        np.broadcast_to(np.asarray(ray_spacing, dtype=np.float64), lengths.shape).copy(),
        plane_side=0.2,  # the memory's regions
    )


def assert_passes_agree(memory: EvidenceMemory, rays: ScanRays, at_least: int) -> None:
    """The compiled passes (reach 8 cm, solid 10 cm deep) are the NumPy twin's, and there are
    more than `at_least` entries passed."""
    entries, counts = occupied_passes(memory, rays, 0.08, 0.1)
    want_entries, want_counts = occupied_passes_reference(memory, rays, 0.08, 0.1)
    assert len(want_entries) > at_least
    np.testing.assert_array_equal(entries, want_entries)
    np.testing.assert_array_equal(counts, want_counts)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("parallel", [False, True])
def test_passes_agree_with_their_numpy_twin(rng, monkeypatch, dim, parallel):
    if parallel:
        monkeypatch.setattr(passes_module, "PARALLEL_MIN_RAYS", 10)
    points = rng.uniform(-2.0, 2.0, (600, dim))
    kinds = rng.choice([OCCUPIED, OCCUPIED_BEHIND, FREE_AT_SURFACE], 600, p=[0.5, 0.3, 0.2])
    memory = memory_of(points, kinds)
    origins = rng.uniform(-3.0, 3.0, (300, dim))
    ends = rng.uniform(-3.0, 3.0, (300, dim))
    spacing = rng.uniform(0.0, 0.03, 300)  # from a depth camera's rays to a 2D laser's
    rays = rays_of(origins, ends, rng.random(300) < 0.7, 0.05, spacing)
    assert_passes_agree(memory, rays, 50)


@pytest.mark.parametrize("dim", [2, 3])
def test_passes_of_sparse_evidence_agree_with_their_numpy_twin(rng, dim):
    """Entries in a few clumps far apart and long rays, many of them through a clump or
    beside it: the passes are those of the NumPy twin."""
    centres = rng.uniform(-6.0, 6.0, (6, dim))
    points = (centres[:, None, :] + rng.uniform(-0.3, 0.3, (6, 60, dim))).reshape(-1, dim)
    memory = memory_of(points, np.full(len(points), OCCUPIED))
    origins = rng.uniform(-8.0, 8.0, (400, dim))
    beside = rng.uniform(-0.4, 0.4, (400, dim))
    ends = 2.0 * centres[rng.integers(0, 6, 400)] - origins + beside
    assert_passes_agree(memory, rays_of(origins, ends, rng.random(400) < 0.7, 0.05), 40)


@pytest.mark.parametrize("dim", [2, 3])
def test_occupied_layout_holds_each_regions_occupied_entries_in_order(rng, dim):
    points = rng.uniform(-2.0, 2.0, (800, dim))
    kinds = rng.choice([OCCUPIED, OCCUPIED_BEHIND, FREE_AT_SURFACE], 800, p=[0.4, 0.2, 0.4])
    memory = memory_of(points, kinds)
    starts, entries, positions = passes_module.occupied_layout(memory)
    occupied = np.flatnonzero(memory.samples().occupied)  # hits and the samples behind them
    assert memory.samples().behind[occupied].mean() > 0.2
    np.testing.assert_array_equal(entries, occupied)
    np.testing.assert_allclose(positions, memory.points_at(occupied), atol=1e-12)
    region = np.searchsorted(memory.region_first(), occupied, side="right") - 1
    np.testing.assert_array_equal(starts, np.searchsorted(region, np.arange(len(starts))))


@pytest.mark.parametrize("dim", [2, 3])
def test_occupied_bitmap_holds_the_regions_with_occupied_entries(rng, dim, monkeypatch):
    """The bitmap's set bits are the regions with occupied entries, numbered row-major from
    the box's least region; a box of more regions than BITMAP_REGIONS has no bitmap, and the
    walk then looks every region up."""
    points = rng.uniform(-2.0, 2.0, (800, dim))
    kinds = rng.choice([OCCUPIED, FREE_AT_SURFACE], 800, p=[0.3, 0.7])
    memory = memory_of(points, kinds)
    starts = passes_module.occupied_layout(memory)[0]
    bits = passes_module.region_bits(dim)
    low, extent, words = passes_module.occupied_bitmap(memory.regions, starts, bits, dim)
    packed = memory.regions[np.diff(starts) > 0] >> 1
    shifts = bits * np.arange(dim - 1, -1, -1)
    regions = ((packed[:, None] >> shifts) & ((1 << bits) - 1)) - (1 << (bits - 1))
    occupied = memory.points_at(np.flatnonzero(memory.samples().occupied))
    assert len(regions) > 20 and np.all(  # each region within a cell of its entries' means
        np.abs(np.floor(occupied / 0.2)[:, None, :] - regions[None]).max(axis=2).min(axis=1) <= 1
    )
    np.testing.assert_array_equal(low, regions.min(axis=0))
    np.testing.assert_array_equal(extent, regions.max(axis=0) - low + 1)
    index = np.ravel_multi_index((regions - low).T, extent)
    set_bits = np.flatnonzero(np.unpackbits(words.view(np.uint8), bitorder="little"))
    np.testing.assert_array_equal(set_bits, np.sort(index))
    monkeypatch.setattr(passes_module, "BITMAP_REGIONS", int(np.prod(extent)) - 1)
    assert len(passes_module.occupied_bitmap.py_func(memory.regions, starts, bits, dim)[2]) == 0


def test_a_pass_needs_the_ray_to_go_on_beyond_the_entry():
    """An entry at x = 1 m: rays that pass it and end well beyond pass it once each; a ray
    that ends within `depth` of it, one that passes too far to the side and one whose free
    part ends before it do not."""
    memory = memory_of(np.array([[1.0, 0.0, 0.0]]), np.array([OCCUPIED]))
    origin = np.zeros(3)
    ends = np.array(
        [
            [3.0, 0.0, 0.0],  # passes through, hits 2 m beyond
            [3.0, 0.02, 0.0],  # passes 1 cm to the side
            [2.0, 0.0, 0.0],  # hits 1 m beyond, no return: passes
            [1.1, 0.0, 0.0],  # hits 0.1 m beyond: within depth
            [3.0, 0.3, 0.0],  # passes 10 cm to the side
            [0.9, 0.0, 0.0],  # ends before it
        ]
    )
    hits = np.array([True, True, False, True, True, True])
    rays = rays_of(np.tile(origin, (6, 1)), ends, hits, 0.05)
    entries, counts = occupied_passes(memory, rays, 0.03, 0.15)
    np.testing.assert_array_equal(entries, [0])
    np.testing.assert_array_equal(counts, [3])


@pytest.mark.parametrize("distance, passed", [(1.0, False), (4.0, True)])
def test_a_pass_reaches_wider_with_range_between_sparse_rays(distance, passed):
    """A ray of a scan whose rays are 0.9 degrees apart (a 16-beam LiDAR's) goes by an entry
    `distance` metres away 8 cm to its side and on 4 m beyond: with a reach of 1.5 cm it
    passes it 4 m away, where its rays are 6.3 cm apart (its reach there: 11 cm), not 1 m
    away (1.6 cm apart), nor anywhere where its scan's rays lie close."""
    # Entry and ray within one region of the memory (20 cm), which the ray crosses.
    origin = np.array([[0.0, 0.0, 0.1]])
    memory = memory_of(np.array([[distance, 0.05, 0.1]]), np.array([OCCUPIED]))
    direction = np.array([distance, 0.13, 0.0]) / np.hypot(distance, 0.13)
    end = origin + (distance + 4.0) * direction
    spacing = np.radians(0.9)
    for ray_spacing, passing in ((spacing, passed), (0.0, False)):
        rays = rays_of(origin, end, np.ones(1, bool), 0.05, ray_spacing)
        entries, counts = occupied_passes(memory, rays, 0.015, 0.15)
        np.testing.assert_array_equal(counts, [1] if passing else [])
        want, want_counts = occupied_passes_reference(memory, rays, 0.015, 0.15)
        np.testing.assert_array_equal(entries, want)
        np.testing.assert_array_equal(counts, want_counts)


def test_free_evidence_is_never_passed():
    memory = memory_of(np.array([[1.0, 0.0]]), np.array([FREE_AT_SURFACE]))
    rays = rays_of(np.zeros((1, 2)), np.array([[3.0, 0.0]]), np.array([True]), 0.05)
    entries, counts = occupied_passes(memory, rays, 0.03, 0.15)
    assert len(entries) == 0 and len(counts) == 0


def test_an_empty_memory_has_nothing_to_pass():
    memory = EvidenceMemory.of_config(3, MapConfig())
    rays = rays_of(np.zeros((1, 3)), np.ones((1, 3)), np.array([True]), 0.05)
    assert len(occupied_passes(memory, rays, 0.03, 0.15)[0]) == 0


def wall_memory() -> EvidenceMemory:
    """Occupied entries on the plane x = 1.1 m, 4 x 4 of them 5 cm apart, in one region."""
    y, z = np.meshgrid(np.arange(4) * 0.05 + 0.025, np.arange(4) * 0.05 + 0.025)
    points = np.column_stack([np.full(16, 1.1), y.ravel(), z.ravel()])
    return memory_of(points, np.full(16, OCCUPIED))


@pytest.mark.parametrize("wall_there", [True, False])
def test_rays_along_a_surface_still_there_do_not_take_it_back(wall_there):
    """A ray 87 degrees to the wall patch's normal, skimming 2 cm in front of it, passes its
    entries; where the batch's other rays land on the wall among them, every one is hit
    again and stays (as rays along the walls of a depth camera's room, which meet them at
    75-85 degrees); where those rays go on 2 m through the wall's old place, none is."""
    memory = wall_memory()
    angle = np.radians(87.0)
    direction = np.array([np.cos(angle), np.sin(angle), 0.0])
    skimming = np.array([1.08, 0.1, 0.1])
    y, z = np.meshgrid(np.linspace(0.03, 0.17, 4), np.linspace(0.03, 0.17, 4))
    on_wall = np.column_stack([np.full(16, 1.1), y.ravel(), z.ravel()])
    origin = np.array([0.0, 0.1, 0.1])
    beyond = origin + (on_wall - origin) * (3.0 if not wall_there else 1.0)
    origins = np.vstack([skimming - 0.5 * direction, np.tile(origin, (16, 1))])
    ends = np.vstack([skimming + 2.0 * direction, beyond])
    rays = rays_of(origins, ends, np.ones(17, dtype=bool), 0.05)
    entries, _ = occupied_passes(memory, rays, 0.04, 0.15)
    assert len(entries) >= 4
    kept = passes_module.hit_again(memory, entries, rays, 0.04)
    assert kept.all() if wall_there else not kept.any()


def test_rays_to_the_floor_behind_pass_what_stood_on_it(monkeypatch):
    """Entries 11 cm above a floor (the lowest of a cart that left) lie within the solid band
    of rays that hit the floor 14 cm beyond them; as the batch's hits there lie on a plane the
    entries are 11 cm off, those rays pass them (and do not once the gap exceeds that)."""
    y = np.array([0.025, 0.075, 0.125, 0.175])
    memory = memory_of(
        np.column_stack([np.full(4, 1.0), y, np.full(4, 0.12)]), np.full(4, OCCUPIED)
    )
    through = np.column_stack([np.full(4, 1.0), y, np.full(4, 0.12)])
    origins = np.column_stack([np.zeros(4), y, np.full(4, 1.5)])
    directions = (through - origins) / np.linalg.norm(through - origins, axis=1)[:, None]
    floor = origins + directions * ((origins[:, 2:] - 0.01) / -directions[:, 2:])
    gx, gy = np.meshgrid(np.linspace(1.02, 1.18, 3), np.linspace(0.02, 0.18, 3))
    around = np.column_stack([gx.ravel(), gy.ravel(), np.full(9, 0.01)])
    ends = np.vstack([floor, around])
    starts = np.vstack([origins, np.tile([0.0, 0.1, 1.5], (9, 1))])
    rays = rays_of(starts, ends, np.ones(13, dtype=bool), 0.05)
    entries, counts = occupied_passes(memory, rays, 0.03, 0.15)
    np.testing.assert_array_equal(entries, np.arange(4))
    want, want_counts = occupied_passes_reference(memory, rays, 0.03, 0.15)
    np.testing.assert_array_equal(entries, want)
    np.testing.assert_array_equal(counts, want_counts)
    monkeypatch.setattr(passes_module, "OFF_PLANE_CELLS", 2.5)  # a gap of 12.5 cm
    assert len(occupied_passes(memory, rays, 0.03, 0.15)[0]) == 0
    assert len(occupied_passes_reference(memory, rays, 0.03, 0.15)[0]) == 0


@pytest.mark.parametrize("distance, passed", [(1.0, True), (3.0, False)])
def test_the_solid_band_deepens_with_range(distance, passed):
    """An entry 40 cm in front of a lone hit (no plane around it): at 1 m the band is 15 cm
    and 0.04 m per square metre of the ray's 1.4 m (23 cm), short of the entry, which is
    passed; at 3 m it is 61 cm deep and covers it."""
    memory = memory_of(np.array([[distance, 0.0, 0.0]]), np.array([OCCUPIED]))
    rays = rays_of(np.zeros((1, 3)), np.array([[distance + 0.4, 0.0, 0.0]]), np.array([True]), 0.05)
    entries, _ = occupied_passes(memory, rays, 0.03, 0.15)
    assert (len(entries) == 1) == passed
    np.testing.assert_array_equal(entries, occupied_passes_reference(memory, rays, 0.03, 0.15)[0])


@pytest.mark.parametrize(
    "range_m, kept", [(10.0, [True, True, False]), (2.0, [True, False, False])]
)
def test_a_batch_hit_near_an_entry_keeps_it(range_m, kept):
    """Entries 2, 15 and 25 cm beside a new hit: within reach (3 cm) the first is kept; at
    10 m the registration slack (2 % of the range, 20 cm) keeps the second too, at 2 m (4 cm)
    it does not."""
    beside = np.array([0.02, 0.15, 0.25])
    points = np.column_stack([np.full(3, range_m), beside, np.zeros(3)])
    memory = memory_of(points, np.full(3, OCCUPIED))
    rays = rays_of(np.zeros((1, 3)), np.array([[range_m, 0.0, 0.0]]), np.array([True]), 0.05)
    near = passes_module.hit_again(memory, np.arange(3), rays, 0.03)
    np.testing.assert_array_equal(near, kept)
    # A batch without hits keeps nothing.
    rays.hits[:] = False
    assert not passes_module.hit_again(memory, np.arange(3), rays, 0.03).any()


@pytest.mark.parametrize(
    "n_entries, spread, n_hits, filtered", [(300, 20.0, 3000, False), (5, 3.0, 20_000, True)]
)
def test_hits_again_match_every_hit_searched_by_brute_force(
    rng, monkeypatch, n_entries, spread, n_hits, filtered
):
    """Entries in a 2 m box and hits of rays from one origin spread over a box `spread`
    metres on each side of it, most far from every entry: what keeps an entry is the nearest
    of all hits, within reach or within the slack of its range, whichever hits the search
    leaves out. Five entries among 20,000 hits: only the hits in the cells beside theirs are
    searched."""
    calls = []
    cells = passes_module.in_neighbour_cells
    monkeypatch.setattr(
        passes_module, "in_neighbour_cells", lambda *a: calls.append(1) or cells(*a)
    )
    entry_points = rng.uniform(0.0, 2.0, (n_entries, 3))
    memory = memory_of(entry_points, np.full(n_entries, OCCUPIED))
    ends = np.concatenate(
        [
            rng.uniform(1.0 - spread, 1.0 + spread, (n_hits, 3)),
            entry_points[: max(1, n_entries // 3)] + 0.02,
        ]
    )
    origin = np.array([-3.0, 0.5, 1.0])
    hits = rng.random(len(ends)) < 0.9
    hits[n_hits:] = True  # the hits beside entries
    rays = rays_of(np.tile(origin, (len(ends), 1)), ends, hits, 0.05)
    entries = np.arange(len(memory))
    points = memory.points_at(entries)
    hit_points = ends[rays.hits]
    distance = np.linalg.norm(points[:, None] - hit_points[None], axis=2).min(axis=1)
    ranges = np.linalg.norm(points - origin, axis=1)
    farthest = passes_module.REGISTRATION_SLACK * rays.lengths.max() + 0.03
    want = (distance <= farthest) & (
        distance <= np.maximum(0.03, passes_module.REGISTRATION_SLACK * ranges)
    )
    got = passes_module.hit_again(memory, entries, rays, 0.03)
    np.testing.assert_array_equal(got, want)
    assert 0 < got.sum() < len(got)
    assert bool(calls) == filtered


@pytest.mark.parametrize("dim", [2, 3])
def test_dense_rays_are_walked_in_a_share_each_standing_for_the_rest(dim):
    """Rays whose ends lie 1 mm apart with a reach of 3 cm: about WALKED_PER_ENTRY of the 60
    (in 2D) or 3,600 (in 3D) within reach of a point are walked, each standing for 1 / share
    rays; rays 5 cm apart, and rays of unknown spacing, are all walked, each for itself."""
    n = 20_000
    rays = rays_of(np.zeros((n, dim)), np.full((n, dim), 2.0), np.ones(n, bool), 0.05)
    length = rays.lengths[0]
    for gap, share in ((0.001, passes_module.WALKED_PER_ENTRY * (0.001 / 0.06) ** (dim - 1)),
                       (0.05, 1.0), (0.0, 1.0)):  # fmt: skip
        rays.ray_spacing[:] = gap / length
        rows, stands_for = passes_module.walked_rays(rays, 0.03)
        assert len(rows) == pytest.approx(share * n, rel=0.01, abs=1)
        np.testing.assert_allclose(stands_for, 1.0 / share)
        # Spread over the rays' order: no stretch of a tenth of them holds twice its share.
        tenths = np.bincount(rows * 10 // n, minlength=10)
        assert tenths.max() <= 2 * share * n / 10 + 1


def test_a_dense_fan_passes_what_all_its_rays_would(monkeypatch):
    """A depth camera's fan of 90 x 90 rays 0.05 degrees apart through a wall patch 2 m away
    and on 1 m beyond (rays 1.7 mm apart there, 2 cm reach): walking a share of them passes
    every entry all of them pass, each as many times within a factor of two (hundreds of
    times: each is taken back whole either way)."""
    memory = wall_memory()
    angles = np.radians(np.arange(-45, 45) * 0.05)
    yaw, pitch = np.meshgrid(angles, angles)
    directions = np.column_stack([np.ones(yaw.size), np.tan(yaw.ravel()), np.tan(pitch.ravel())])
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    origin = np.array([-0.9, 0.1, 0.1])
    rays = rays_of(
        np.tile(origin, (len(directions), 1)),
        origin + 3.1 * directions,
        np.ones(len(directions), dtype=bool),
        0.05,
        np.radians(0.05),
    )
    walked, _ = passes_module.walked_rays(rays, 0.02)
    assert len(walked) < 0.1 * len(rays)
    entries, counts = occupied_passes(memory, rays, 0.02, 0.15)
    monkeypatch.setattr(passes_module, "WALKED_PER_ENTRY", np.inf)  # every ray walked
    all_entries, all_counts = occupied_passes(memory, rays, 0.02, 0.15)
    np.testing.assert_array_equal(entries, all_entries)
    assert len(entries) == 16
    assert np.all((counts > all_counts / 2) & (counts < 2 * all_counts))
    assert counts.min() > 100
