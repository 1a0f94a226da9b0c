"""The evidence memory: one weighted mean per cell and kind, replay in the proportions seen
from the regions a batch reaches, evidence waiting for a cluster, and its arrays for files."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.observations.evidence import FREE_ALONG_RAY, FREE_AT_SURFACE, OCCUPIED, sample_flags
from ehm.core.observations.memory import (
    CLUSTERED,
    MIN_WEIGHT,
    OFFSET_STEPS,
    PASSED,
    EvidenceMemory,
    _find,
    batch_entries,
    batch_entries_reference,
    heavy_threshold,
    merge_entries,
    merge_entries_reference,
    region_layout,
    region_layout_reference,
    threshold_draw,
    visit_rows,
    visit_rows_reference,
)
from ehm.core.observations.memory_keys import (
    REGION_BITS,
    memory_keys,
    reached_regions,
)
from ehm.core.observations.samples import TrainingSamples

# Fine cells of 0.25 m (regions of 1 m around hits), coarse ones of 2.5 m (regions of 7.5 m).
SIDES = (0.25, 2.5)


def samples_at(points, kind=FREE_AT_SURFACE, weight=None) -> TrainingSamples:
    points = np.asarray(points, dtype=np.float64)
    occupied, at_surface = sample_flags(np.full(len(points), kind))
    return TrainingSamples(points, occupied, at_surface, weight)


def insert(memory, samples, clustered=True):
    memory.insert(memory.visit(samples), np.full(len(samples), clustered))


@pytest.mark.parametrize("dim", [2, 3])
def test_a_visit_finds_the_entries_of_a_batch_as_its_numpy_twin_does(rng, dim):
    """A memory of scattered evidence of every kind, and a batch half of whose cells it holds:
    each sample's entry and the entries of every region around the batch agree with a search
    of the memory's sorted keys."""
    memory = EvidenceMemory(dim, True, SIDES)
    kinds = rng.integers(0, 3, 3000)
    kept = rng.uniform(-20.0, 20.0, (3000, dim))
    occupied, at_surface = sample_flags(kinds)
    insert(memory, TrainingSamples(kept, occupied, at_surface))
    points = np.concatenate([kept[:500], rng.uniform(-25.0, 25.0, (500, dim))])
    keys = memory_keys(points, kinds[:1000], SIDES)
    reached = reached_regions(
        np.concatenate([points, points]), np.repeat([False, True], 1000), SIDES
    )
    table = memory.region_table()
    assert memory.region_table() is table  # made once for the regions as they stand
    entries, near = visit_rows(
        *table, memory.region_first(), memory.region_sizes, memory.cells, keys, reached
    )
    want_entries, want_near = visit_rows_reference(memory.keys(), keys, reached)
    assert np.all(entries[:500] >= 0) and 0 < np.sum(entries[500:] >= 0) < 500
    assert len(near) > 1000
    np.testing.assert_array_equal(entries, want_entries)
    np.testing.assert_array_equal(near, want_near)


def test_an_entry_sums_the_weight_and_mean_of_its_cell_and_kind():
    memory = EvidenceMemory(2, True, SIDES)
    insert(memory, samples_at([[0.05, 0.05], [0.15, 0.2]], weight=np.array([1.0, 3.0])))
    insert(memory, samples_at([[0.1, 0.1]], weight=np.array([4.0])))
    # Another kind in the same cell, and another cell: entries of their own.
    insert(memory, samples_at([[0.1, 0.1]], kind=OCCUPIED))
    insert(memory, samples_at([[0.3, 0.1]]))
    assert len(memory) == 3 and np.all(np.diff(memory.keys()) > 0)
    entry = _find(
        memory.keys(), memory_keys(np.array([[0.1, 0.1]]), np.array([FREE_AT_SURFACE]), SIDES)
    )
    assert memory.weight[entry[0]] == 8.0
    mean = (1.0 * np.array([0.05, 0.05]) + 3.0 * np.array([0.15, 0.2]) + 4.0 * 0.1) / 8.0
    # The mean's place in its cell of 0.25 m is kept to a step of 0.25 / 255 m.
    np.testing.assert_allclose(
        memory._samples_at(entry, memory.keys()).points[0], mean, atol=0.25 / 255
    )


def test_replay_weighs_ratio_times_the_batch_in_each_group_in_proportion_to_seen():
    memory = EvidenceMemory(2, True, SIDES)
    insert(memory, samples_at([[0.1, 0.1], [0.6, 0.1]], weight=np.array([1.0, 3.0])))
    insert(memory, samples_at([[0.2, 0.2], [3.0, 0.5]], FREE_ALONG_RAY, np.array([2.0, 6.0])))
    batch = TrainingSamples(
        np.array([[0.4, 0.4], [0.5, 0.5], [1.0, 0.5]]),
        np.array([True, False, False]),
        np.array([True, True, False]),
        np.array([5.0, 1.0, 10.0]),
    )
    replayed = memory.replay(0.5, memory.visit(batch))
    surface = replayed.at_surface
    assert replayed.weight[surface].sum() == pytest.approx(0.5 * 6.0)
    assert replayed.weight[~surface].sum() == pytest.approx(0.5 * 10.0)
    np.testing.assert_allclose(np.sort(replayed.weight[surface]), [0.75, 2.25])
    np.testing.assert_allclose(np.sort(replayed.weight[~surface]), [1.25, 3.75])


def test_threshold_draw_keeps_the_heavy_weights_and_each_light_one_in_expectation(rng):
    weight = np.concatenate([[5.0, 3.0], rng.uniform(0.01, 0.2, 98)])
    drawn_weight = np.zeros_like(weight)
    for seed in range(4000):
        rows, stands_for = threshold_draw(weight, 20, np.random.default_rng(seed))
        assert len(rows) == 20 and np.all(np.diff(rows) > 0)
        assert stands_for.sum() == pytest.approx(weight.sum())
        np.testing.assert_array_equal(stands_for[:2], [5.0, 3.0])  # kept as they are
        light = stands_for[2:]
        np.testing.assert_allclose(light, light[0])  # each drawn one stands for the threshold
        assert light[0] > weight[2:].max()
        drawn_weight[rows] += stands_for
    np.testing.assert_allclose(drawn_weight / 4000, weight, atol=0.02)


def test_the_heavy_threshold_is_the_one_the_sorted_weights_give(rng):
    for _ in range(200):
        n = int(rng.integers(3, 300))
        count = int(rng.integers(1, n))
        weight = rng.lognormal(0.0, rng.uniform(0.1, 3.0), n)
        threshold, heavy = heavy_threshold(weight, count)
        # By definition: the k heaviest rows kept, the rest shared out in count - k steps of
        # t, for the least k whose next row lies below its t.
        descending = np.sort(weight)[::-1][:count]
        rest = weight.sum() - np.concatenate([[0.0], np.cumsum(descending[:-1])])
        steps = rest / (count - np.arange(count))
        k = int(np.argmax(descending < steps))
        assert threshold == pytest.approx(steps[k], rel=1e-9)  # sums in another order
        assert heavy.sum() == k and np.all(weight[heavy] >= threshold)


def test_replay_beyond_its_cap_is_drawn_with_the_same_weight_in_all(rng):
    memory = EvidenceMemory(2, True, SIDES)
    points, weight = rng.uniform(0.0, 6.0, (2000, 2)), rng.uniform(0.5, 2.0, 2000)
    insert(memory, samples_at(points, weight=weight))
    visit = memory.visit(samples_at(rng.uniform(0.0, 6.0, (40, 2))))
    every = memory.replay(1.0, visit)
    capped = memory.replay(1.0, visit, 1.5, np.random.default_rng(1))
    assert len(every) > 60 and len(capped) == 60
    assert capped.weight.sum() == pytest.approx(every.weight.sum())
    assert np.isin(capped.points.view(complex), every.points.view(complex)).all()
    same = memory.replay(1.0, visit, len(every) / 40, np.random.default_rng(1))
    np.testing.assert_array_equal(same.weight, every.weight)


def test_replay_comes_from_the_regions_the_batch_reaches_alone():
    memory = EvidenceMemory(2, True, SIDES)
    insert(memory, samples_at([[0.5, 0.5], [4.5, 0.5]]))
    replayed = memory.replay(1.0, memory.visit(samples_at([[0.9, 0.9]])))
    np.testing.assert_allclose(replayed.points, [[0.5, 0.5]], atol=1e-6)
    assert len(memory.replay(1.0, memory.visit(samples_at([[20.0, 20.0]])))) == 0


def test_region_keys_tell_apart_regions_and_kinds_alone():
    memory = EvidenceMemory(2, True, SIDES)
    around_hits = samples_at([[0.1, 0.1], [0.9, 0.9], [1.1, 0.1]])
    occupied = samples_at([[0.1, 0.1]], OCCUPIED)
    along_rays = samples_at([[0.1, 0.1], [7.4, 7.4], [7.6, 0.1]], FREE_ALONG_RAY)
    keys = memory.region_keys(around_hits + occupied + along_rays)
    # Regions are 1 m wide around hits and 7.5 m along rays, one for each kind.
    assert keys[0] == keys[1] != keys[2]
    assert keys[3] != keys[0] and keys[3] not in keys[4:]
    assert keys[4] == keys[5] != keys[6] and keys[4] not in keys[:4]


def test_evidence_waits_for_a_cluster_until_marked():
    memory = EvidenceMemory(2, True, SIDES)
    insert(memory, samples_at([[0.1, 0.1], [0.6, 0.6]], weight=np.array([2.0, 3.0])), False)
    visit = memory.visit(samples_at([[0.2, 0.2]]))
    pending = memory.pending(visit)
    np.testing.assert_array_equal(pending.samples.weight, [2.0])
    memory.mark_clustered(pending, np.array([True]))
    assert len(memory.pending(visit).samples) == 0
    assert len(memory.pending(memory.visit(samples_at([[0.7, 0.7]]))).samples) == 1


def test_a_memory_that_keeps_nothing_stays_empty():
    memory = EvidenceMemory.of_config(2, MapConfig(keep_evidence=False))
    insert(memory, samples_at([[0.1, 0.1]]), False)
    visit = memory.visit(samples_at([[0.1, 0.1]]))
    assert len(memory) == 0 and len(memory.replay(1.0, visit)) == 0
    assert len(memory.pending(visit).samples) == 0


def test_arrays_round_trip_and_kept_samples_load_as_evidence(rng):
    config = MapConfig()
    memory = EvidenceMemory.of_config(3, config)
    points = rng.uniform(-3, 3, (500, 3))
    samples = samples_at(points, weight=rng.uniform(1, 4, 500))
    clustered = rng.random(500) < 0.5
    memory.insert(memory.visit(samples), clustered)
    restored = EvidenceMemory.from_arrays(3, config, memory.arrays())
    for name, array in memory.arrays().items():
        np.testing.assert_array_equal(getattr(restored, name), array)
    again = EvidenceMemory.of_samples(3, config, samples, clustered)
    for name, array in memory.arrays().items():
        np.testing.assert_array_equal(getattr(again, name), array)
    assert memory.weight.sum() == pytest.approx(samples.weight.sum())


@pytest.mark.parametrize("dim", [2, 3])
def test_a_batchs_entries_agree_with_their_numpy_twin(rng, dim):
    points = rng.uniform(-3.0, 3.0, (600, dim))
    points = np.concatenate([points, points[:200] + 0.01])  # cells met more than once
    kinds = rng.integers(0, 3, len(points))
    keys = memory_keys(points, kinds, SIDES)
    order = np.argsort(keys)
    batch = (keys[order], order, rng.uniform(0.5, 4.0, len(points)), points)
    clustered = rng.random(len(points)) < 0.3
    got = batch_entries(*batch, clustered, *SIDES)
    want = batch_entries_reference(*batch, clustered, *SIDES)
    assert len(got[0]) < len(points)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[3], want[3])
    for compiled, reference in zip(got[1:3], want[1:3], strict=True):
        np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-9)
    assert np.all((want[2] >= 0) & (want[2] <= OFFSET_STEPS * want[1][:, None] * (1 + 1e-12)))


@pytest.mark.parametrize("repeats", [(1, 1, 1), (5, 3), (400, 2, 1, 300)])
def test_a_batchs_entries_in_parts_agree_with_their_numpy_twin(rng, repeats):
    """Fewer samples than parts, and cells whose samples span several parts' ranges: each
    cell's samples are summed in one range, as the NumPy twin sums them."""
    keys = np.repeat(np.sort(rng.choice(10**6, len(repeats), replace=False)), repeats)
    n = len(keys)
    order = rng.permutation(n)
    batch = (keys.astype(np.int64), order, rng.uniform(0.5, 4.0, n), rng.uniform(-3, 3, (n, 3)))
    clustered = rng.random(n) < 0.3
    got = batch_entries(*batch, clustered, *SIDES)
    want = batch_entries_reference(*batch, clustered, *SIDES)
    np.testing.assert_array_equal(got[0], np.unique(keys))
    np.testing.assert_array_equal(got[3], want[3])
    for compiled, reference in zip(got[1:3], want[1:3], strict=True):
        np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-9)


def test_merging_entries_agrees_with_its_numpy_twin(rng):
    m, n = 400, 300
    keys = np.sort(rng.choice(2000, m, replace=False)).astype(np.int64)
    weight = rng.uniform(1, 5, m).astype(np.float32)
    weight[rng.random(m) < 0.2] = 0.0  # emptied entries: gone unless new evidence comes
    memory = (
        keys,
        weight,
        rng.integers(0, OFFSET_STEPS + 1, (m, 3)).astype(np.uint8),
        rng.integers(0, 4, m).astype(np.uint8),
    )
    new_keys = np.sort(rng.choice(2000, n, replace=False)).astype(np.int64)
    new_weight = rng.uniform(1, 5, n)
    batch = (new_keys, new_weight, new_weight[:, None] * rng.uniform(0, OFFSET_STEPS, (n, 3)))
    formed = rng.random(n) < 0.5
    merged = merge_entries(*memory, *batch, formed)
    expected = merge_entries_reference(*memory, *batch, formed)
    emptied = keys[weight == 0.0]
    gone = np.setdiff1d(emptied, new_keys)
    assert 0 < len(gone) < len(emptied)  # some emptied entries get new evidence, some not
    np.testing.assert_array_equal(merged[0], np.setdiff1d(np.union1d(keys, new_keys), gone))
    for got, want in zip(merged, expected, strict=True):
        np.testing.assert_array_equal(got, want)


def test_the_region_layout_agrees_with_its_numpy_twin(rng):
    regions = np.sort(rng.choice(10**6, 300, replace=False)).astype(np.int64)
    cells = [
        np.sort(rng.choice(2**REGION_BITS, rng.integers(1, 60), replace=False)) for _ in regions
    ]
    keys = np.concatenate([(r << REGION_BITS) | c for r, c in zip(regions, cells, strict=True)])
    got, want = region_layout(keys), region_layout_reference(keys)
    for compiled, reference in zip(got, want, strict=True):
        assert compiled.dtype == reference.dtype
        np.testing.assert_array_equal(compiled, reference)
    np.testing.assert_array_equal(got[0], regions)
    np.testing.assert_array_equal(got[1], [len(c) for c in cells])
    assert [len(a) for a in region_layout(np.zeros(0, dtype=np.int64))] == [0, 0, 0]


def test_a_memory_of_format_13_keeps_its_entries(rng):
    """Keys (n,) int64 and places in 65535 steps, as format 13 kept them, load region by
    region with their places to the nearest of OFFSET_STEPS."""
    config = MapConfig()
    memory = EvidenceMemory.of_config(3, config)
    insert(memory, samples_at(rng.uniform(-3, 3, (500, 3)), weight=rng.uniform(1, 4, 500)))
    old = {
        "keys": memory.keys(),
        "weight": memory.weight,
        "place": (memory.place.astype(np.uint16) * 257),
        "clustered": memory.flags & CLUSTERED != 0,
    }
    loaded = EvidenceMemory.from_arrays(3, config, old)
    for name, array in memory.arrays().items():
        np.testing.assert_array_equal(getattr(loaded, name), array, err_msg=name)


@pytest.mark.parametrize(("m", "n"), [(0, 50), (50, 0), (3, 40), (40, 3), (5000, 4000)])
def test_merging_in_parts_agrees_with_its_numpy_twin_for_any_sizes(rng, m, n):
    """Fewer entries than parts, no entries, no new keys, and many of both: the parts of the
    merge meet where the NumPy twin's one merge has them."""
    keys = np.sort(rng.choice(20 * (m + n), m, replace=False)).astype(np.int64)
    weight = rng.uniform(1, 5, m).astype(np.float32)
    weight[rng.random(m) < 0.2] = 0.0
    memory = (keys, weight, rng.integers(0, OFFSET_STEPS + 1, (m, 2)).astype(np.uint8))
    memory += (rng.integers(0, 4, m).astype(np.uint8),)
    new_keys = np.sort(rng.choice(20 * (m + n), n, replace=False)).astype(np.int64)
    new_weight = rng.uniform(1, 5, n)
    batch = (new_keys, new_weight, new_weight[:, None] * rng.uniform(0, OFFSET_STEPS, (n, 2)))
    formed = rng.random(n) < 0.5
    merged = merge_entries(*memory, *batch, formed)
    for got, want in zip(merged, merge_entries_reference(*memory, *batch, formed), strict=True):
        np.testing.assert_array_equal(got, want)


def test_merging_keeps_clustered_and_clears_passed_where_new_evidence_comes():
    keys = np.array([10, 20], dtype=np.int64)
    flags = np.array([CLUSTERED | PASSED, PASSED], dtype=np.uint8)
    memory = (keys, np.ones(2, dtype=np.float32), np.zeros((2, 2), dtype=np.uint8), flags)
    batch = (np.array([20, 30], dtype=np.int64), np.ones(2), np.zeros((2, 2)))
    merged = merge_entries(*memory, *batch, np.array([False, True]))
    np.testing.assert_array_equal(merged[3], [CLUSTERED | PASSED, 0, CLUSTERED])


def test_evidence_is_taken_back_from_the_second_batch_of_passes_on():
    memory = EvidenceMemory(2, True, SIDES)
    insert(memory, samples_at([[0.1, 0.1], [0.6, 0.1], [1.1, 0.1]], OCCUPIED, np.full(3, 8.0)))
    entries, passes = np.arange(3), np.array([1, 2, 3])
    first = memory.retract(entries, passes, 0.5, np.array([False, False, True]))
    assert len(first.entries) == 0
    np.testing.assert_array_equal(memory.weight, [8.0, 8.0, 8.0])
    np.testing.assert_array_equal(memory.flags & PASSED != 0, [True, True, False])
    second = memory.retract(entries, passes, 0.5, np.zeros(3, dtype=bool))
    np.testing.assert_array_equal(second.entries, [0, 1])
    np.testing.assert_array_equal(second.before, [8.0, 8.0])
    np.testing.assert_array_equal(second.after, [4.0, 2.0])
    np.testing.assert_array_equal(memory.weight, [4.0, 2.0, 8.0])
    # Weights below MIN_WEIGHT become 0, and the entry goes with the next insert.
    memory.retract(np.array([1]), np.array([20]), 0.5, np.zeros(1, dtype=bool))
    assert memory.weight[1] == 0.0 < MIN_WEIGHT
    insert(memory, samples_at([[3.0, 3.0]]))
    np.testing.assert_array_equal(memory.weight, [4.0, 8.0, 1.0])


def test_the_occupied_entries_near_others_are_those_of_their_regions():
    memory = EvidenceMemory(2, True, SIDES)
    points = [[0.1, 0.1], [0.9, 0.9], [1.1, 0.1], [5.0, 5.0]]
    insert(memory, samples_at(points, OCCUPIED))
    insert(memory, samples_at([[0.5, 0.5]], FREE_AT_SURFACE))
    occupied = memory.samples().occupied
    first = np.flatnonzero(occupied & np.all(memory.samples().points < 1.0, axis=1))[0]
    near = memory.occupied_near(np.array([first]))
    np.testing.assert_allclose(memory.points_at(near), [[0.1, 0.1], [0.9, 0.9]], atol=1e-3)


def test_a_timed_memory_keeps_when_each_region_last_had_evidence():
    memory = EvidenceMemory(2, True, SIDES, timed=True)
    # Regions of 1 m around hits: (0, 0) and (3, 3).
    memory.insert(memory.visit(samples_at([[0.1, 0.1], [3.5, 3.5]])), np.ones(2, bool), 10.0)
    np.testing.assert_array_equal(memory.seen, [10.0, 10.0])
    # A later batch in a new region (1, 1) and in (3, 3): (0, 0) keeps its time.
    memory.insert(memory.visit(samples_at([[1.5, 1.5], [3.2, 3.2]])), np.ones(2, bool), 12.0)
    np.testing.assert_array_equal(memory.seen, [10.0, 12.0, 12.0])
    # Each region's entries keep a share of their weight (region (3, 3) holds two); a weight
    # under MIN_WEIGHT becomes 0, and its entry goes with the next insert.
    memory.fade(np.array([0.5, 1.0, MIN_WEIGHT / 4]))
    np.testing.assert_allclose(memory.weight, [0.5, 1.0, 0.0, 0.0])
    memory.insert(memory.visit(samples_at([[0.2, 0.2]])), np.ones(1, bool), 13.0)
    np.testing.assert_allclose(memory.weight, [1.5, 1.0])
    np.testing.assert_array_equal(memory.seen, [13.0, 12.0])
    restored = EvidenceMemory.from_arrays(2, MapConfig(forget_after=5.0), memory.arrays())
    np.testing.assert_array_equal(restored.seen, memory.seen)


def test_an_untimed_memory_keeps_no_times():
    memory = EvidenceMemory.of_config(2, MapConfig())
    memory.insert(memory.visit(samples_at([[0.1, 0.1]])), np.ones(1, bool), 3.0)
    assert not memory.timed and len(memory.seen) == 0
    assert EvidenceMemory.of_config(2, MapConfig(forget_after=1.0)).timed
