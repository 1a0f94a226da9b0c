"""The sample memory: reservoirs per cell, replay in the proportions seen, samples waiting for a
cluster, and its arrays for map files."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.memory import EMPTY, SampleMemory
from ehm.core.samples import TrainingSamples


def samples_at(points, occupied=False, at_surface=True) -> TrainingSamples:
    points = np.asarray(points, dtype=np.float64)
    n = len(points)
    return TrainingSamples(
        points, np.broadcast_to(occupied, n).copy(), np.broadcast_to(at_surface, n).copy()
    )


def insert(memory, samples, clustered, rng):
    memory.insert(memory.visit(samples), clustered, rng)


def uniform_in_cell(rng, n, corner, side=1.0) -> TrainingSamples:
    return samples_at(np.asarray(corner) + side * rng.random((n, 2)) * 0.999)


def test_each_cell_keeps_at_most_per_cell_and_counts_what_it_saw(rng):
    memory = SampleMemory(2, 4, (1.0, 5.0))
    insert(memory, uniform_in_cell(rng, 10, (0, 0)), np.ones(10, bool), rng)
    insert(memory, uniform_in_cell(rng, 3, (1, 0)), np.ones(3, bool), rng)
    insert(memory, uniform_in_cell(rng, 5, (0, 0)), np.ones(5, bool), rng)
    # Free samples along rays live in their own, larger cells.
    insert(memory, samples_at([[0.5, 0.5]], at_surface=False), np.ones(1, bool), rng)
    assert memory.n_cells == 3 and len(memory) == 4 + 3 + 1
    cells = memory.cell_arrays()
    assert sorted(cells["seen"].tolist()) == [1.0, 3.0, 15.0]
    assert sorted(cells["filled"].tolist()) == [1, 3, 4]
    assert np.sum(cells["priority"] != EMPTY) == 8
    # Kept samples fill the first slots of a cell, and sit inside it.
    for row in range(memory.n_cells):
        filled = cells["filled"][row]
        assert np.all(cells["priority"][row, :filled] != EMPTY)
        assert np.all(cells["priority"][row, filled:] == EMPTY)
    assert np.all(np.diff(memory.keys) > 0)


def test_a_cell_keeps_a_uniform_subset_of_all_it_saw(rng):
    """Inserted in 20 batches of 10, every sample is kept with the same chance, per_cell / 200,
    whether it came first or last."""
    kept_batches = []
    for _ in range(300):
        memory = SampleMemory(2, 8, (1.0, 1.0))
        for batch in range(20):
            points = np.column_stack([np.full(10, batch / 20), rng.random(10) * 0.999])
            insert(memory, samples_at(points), np.ones(10, bool), rng)
        kept_batches.append(np.round(memory.points[0, :, 0] * 20).astype(int))
    counts = np.bincount(np.concatenate(kept_batches), minlength=20)
    expected = 300 * 8 / 20
    assert counts.sum() == 300 * 8
    # Binomial spread: 120 +- 11 per batch; the first and last halves keep alike.
    assert np.all(np.abs(counts - expected) < 5 * np.sqrt(expected))
    assert abs(counts[:10].sum() - counts[10:].sum()) < 0.1 * counts.sum()


def test_replay_draws_cells_in_proportion_to_what_they_saw(rng):
    memory = SampleMemory(2, 4, (1.0, 1.0))
    insert(memory, uniform_in_cell(rng, 900, (0, 0)), np.ones(900, bool), rng)
    insert(memory, uniform_in_cell(rng, 100, (1, 0)), np.ones(100, bool), rng)
    insert(memory, uniform_in_cell(rng, 50, (7, 7)), np.ones(50, bool), rng)
    near = samples_at([[0.5, 0.5], [1.5, 0.5]])
    replayed = memory.replay(10_000, memory.visit(near), rng)  # per sample of the 2
    assert len(replayed) == 20000 and replayed.points.dtype == np.float64
    in_first = np.all((replayed.points >= 0) & (replayed.points < 1), axis=1)
    in_second = (replayed.points[:, 0] >= 1) & (replayed.points[:, 0] < 2)
    assert in_first.sum() + in_second.sum() == 20000  # never the far cell
    assert in_first.mean() == pytest.approx(0.9, abs=0.01)
    # Within a cell, the kept samples come back alike.
    _, per_sample = np.unique(replayed.points[in_second], axis=0, return_counts=True)
    assert len(per_sample) == 4 and per_sample.min() > 0.8 * per_sample.max()


def test_replay_reaches_cells_of_either_kind_around_the_new_samples(rng):
    memory = SampleMemory(2, 4, (1.0, 5.0))
    hits = samples_at([[0.5, 0.5], [0.6, 0.6]], occupied=True)
    insert(memory, hits, np.ones(2, bool), rng)
    # Free samples along a later ray pass through the cell of those hits.
    ray = samples_at([[0.55, 0.4]], at_surface=False)
    replayed = memory.replay(50, memory.visit(ray), rng)
    assert len(replayed) == 50 and replayed.occupied.all() and replayed.at_surface.all()
    far = memory.visit(samples_at([[3.5, 3.5]]))
    assert len(memory.replay(50, far, rng)) == 0
    empty = SampleMemory(2, 4, (1.0, 5.0))
    assert len(empty.replay(50, empty.visit(ray), rng)) == 0


def test_replay_matches_the_share_of_each_kind_of_the_new_samples(rng):
    memory = SampleMemory(2, 8, (1.0, 1.0))
    around_hits = uniform_in_cell(rng, 100, (0, 0))
    along_rays = samples_at(uniform_in_cell(rng, 5000, (1, 0)).points, at_surface=False)
    insert(memory, around_hits, np.ones(100, bool), rng)
    insert(memory, along_rays, np.ones(5000, bool), rng)
    # A new scan with a quarter of its samples around hits, in both cells: though the cell
    # along rays saw 50 times more, a quarter of the replay comes from the cell around hits.
    new = samples_at([[0.5, 0.5], [1.5, 0.5], [1.6, 0.5], [1.7, 0.5]])
    new = TrainingSamples(new.points, new.occupied, np.array([True, False, False, False]))
    replayed = memory.replay(1000, memory.visit(new), rng)
    assert len(replayed) == 4000 and replayed.at_surface.sum() == 1000


def test_samples_without_cluster_wait_in_their_cell_until_clustered(rng):
    memory = SampleMemory(2, 8, (1.0, 1.0))
    first = uniform_in_cell(rng, 6, (0, 0))
    clustered = np.array([True, True, False, False, False, True])
    insert(memory, first, clustered, rng)
    insert(memory, uniform_in_cell(rng, 3, (2, 0)), np.zeros(3, bool), rng)
    pending = memory.pending(memory.visit(uniform_in_cell(rng, 2, (0, 0))))
    # Kept in single precision: 1e-7 of the coordinates.
    np.testing.assert_array_equal(
        np.sort(pending.samples.points[:, 0]),
        np.sort(first.points[~clustered, 0].astype(np.float32)),
    )
    memory.mark_clustered(pending, np.array([True, False, True]))
    assert len(memory.pending(memory.visit(uniform_in_cell(rng, 2, (0, 0)))).samples) == 1
    assert len(memory.pending(memory.visit(uniform_in_cell(rng, 2, (5, 5)))).samples) == 0


def test_cell_keys_tell_neighbours_and_kinds_apart_and_refuse_far_points():
    memory = SampleMemory(3, 8, (0.1, 0.5))
    points = np.array([[-0.05, 0, 0], [0.05, 0, 0], [0, -0.05, 0], [0, 0, -0.05], [0, 0, 0]])
    keys = memory.cell_keys(points, np.ones(5, bool))
    assert len(np.unique(keys)) == 4  # the origin shares the cell of (0.05, 0, 0)
    assert memory.cell_keys(points[:1], np.zeros(1, bool)) != keys[0]
    with pytest.raises(ValueError, match="memory_per_cell=0"):
        memory.cell_keys(np.array([[1e5, 0.0, 0.0]]), np.ones(1, bool))


def test_arrays_restore_a_memory_that_goes_on_alike(rng):
    memory = SampleMemory.of_config(2, MapConfig(memory_per_cell=3))
    for corner in [(0, 0), (0.2, 0), (3, 3)]:
        insert(memory, uniform_in_cell(rng, 7, corner, 0.3), rng.random(7) < 0.5, rng)
    restored = SampleMemory.from_arrays(2, MapConfig(memory_per_cell=3), memory.arrays())
    more = uniform_in_cell(rng, 9, (0.1, 0.1), 0.4)
    for copy in (memory, restored):
        insert(copy, more, np.zeros(9, bool), np.random.default_rng(5))
    for name, array in memory.arrays().items():
        np.testing.assert_array_equal(restored.arrays()[name], array, err_msg=name)


def test_a_memory_of_no_samples_keeps_and_replays_nothing(rng):
    memory = SampleMemory.of_config(3, MapConfig(memory_per_cell=0))
    samples = samples_at(rng.random((20, 3)))
    insert(memory, samples, np.zeros(20, bool), rng)
    assert len(memory) == 0 and memory.n_cells == 0
    visit = memory.visit(samples)
    assert len(memory.replay(10, visit, rng)) == 0
    assert len(memory.pending(visit).samples) == 0
    # Without a memory, samples may lie anywhere.
    far = samples_at(np.array([[1e9, 0.0, 0.0]]))
    insert(memory, far, np.zeros(1, bool), rng)
    assert len(memory) == 0 and memory.n_cells == 0
