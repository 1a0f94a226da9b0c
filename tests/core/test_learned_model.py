"""What a map has learned: restored from its state, read at points, copied for grids."""

import numpy as np

from ehm.core.learned_model import LearnedModel, finite_rows


def test_a_model_restored_from_a_state_reads_and_draws_as_the_map(room_map, rng):
    model = LearnedModel.of_state(room_map.state())
    points = rng.uniform([-4.0, -3.0, 0.0], [4.0, 3.0, 3.0], (500, 3))
    scores, variance = model.log_odds(points, "batch", True)
    np.testing.assert_array_equal(scores, room_map.decision_function(points))
    expected = room_map.decision_function(points, return_variance=True)[1]
    np.testing.assert_array_equal(variance, expected)
    assert model.rng_state == room_map.model_.rng_state


def test_rows_that_are_not_finite_read_nan(room_map):
    model = room_map.model_
    points = np.array([[0.0, 0.0, 1.0], [np.nan, 0.0, 1.0], [0.0, np.inf, 1.0]])
    finite, query = finite_rows(points)
    assert finite.tolist() == [True, False, False] and query.flags.c_contiguous
    scores, variance = model.log_odds(points, "exact", True)
    assert np.isfinite(scores[0]) and np.isnan(scores[1:]).all() and np.isnan(variance[1:]).all()
    gradients = model.gradients(points, "exact")
    assert np.isfinite(gradients[0]).all() and np.isnan(gradients[1:]).all()


def test_snapshots_are_read_only_copies_shifted_as_asked(room_map):
    model, lineage = room_map.model_, object()
    kept = model.snapshot(lineage)
    np.testing.assert_array_equal(kept.means, model.clusters.means)
    assert kept.lineage is lineage and not kept.means.flags.writeable
    assert not np.shares_memory(kept.weights, model.clusters.weights)
    shift = np.array([1024.0, -2048.0, 0.0])
    np.testing.assert_array_equal(model.snapshot(lineage, shift).means, kept.means + shift)
    np.testing.assert_array_equal(model.snapshot(lineage, np.zeros(3)).means, kept.means)
    assert kept.intercept == model.intercept
