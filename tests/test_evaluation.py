import numpy as np
import pytest

from ehm.comparison import EvalRecord, summarise
from ehm.evaluation import average_ranks, f1_score, held_out_rays, roc_auc, score


def test_scores_against_hand_computed_values():
    labels = np.array([1, 1, 0, 0, 1], dtype=bool)
    probability = np.array([0.9, 0.4, 0.6, 0.1, 0.7])
    # predicted occupied: 1 0 1 0 1 -> 3 of 5 right; TP 2, FP 1, FN 1 -> F1 = 4 / 6
    # ROC-AUC: positives 0.9, 0.4, 0.7 against negatives 0.6, 0.1: 2 + 1 + 2 of 6 pairs
    s = score(labels, probability, unknown=np.array([0, 0, 1, 0, 0], dtype=bool))
    assert s.accuracy == pytest.approx(0.6)
    assert s.f1 == pytest.approx(2 / 3)
    assert s.auc == pytest.approx(5 / 6)
    assert s.unknown == pytest.approx(0.2)


def test_probability_one_half_counts_as_free():
    s = score(np.array([True, False]), np.array([0.5, 0.2]))
    assert s.accuracy == 0.5 and s.f1 == 0.0


def test_roc_auc_counts_ties_as_one_half():
    # pairs: (0.8 vs 0.8) 1/2, (0.8 vs 0.1) 1, (0.3 vs 0.8) 0, (0.3 vs 0.1) 1 -> 2.5 / 4
    assert roc_auc(np.array([1, 0, 1, 0]), np.array([0.8, 0.8, 0.3, 0.1])) == 0.625
    assert roc_auc(np.array([1, 0, 1, 0]), np.full(4, 0.5)) == 0.5
    assert roc_auc(np.array([1, 1, 0]), np.array([0.9, 0.8, 0.1])) == 1.0
    with pytest.raises(ValueError, match="both occupied and free"):
        roc_auc(np.array([1, 1]), np.array([0.2, 0.3]))


def test_average_ranks_share_ties():
    ranks = average_ranks(np.array([3.0, 1.0, 3.0, 2.0, 3.0]))
    np.testing.assert_array_equal(ranks, [4.0, 1.0, 4.0, 2.0, 4.0])


def test_f1_of_nothing_predicted_and_nothing_present_is_zero():
    assert f1_score(np.zeros(3, bool), np.zeros(3, bool)) == 0.0
    assert f1_score(np.array([1, 0, 1]), np.array([1, 1, 0])) == pytest.approx(0.5)


def test_split_is_reproducible_for_a_seed(room):
    a = held_out_rays(room.scans, 0.6, 0.05, seed=3)
    b = held_out_rays(room.scans, 0.6, 0.05, seed=3)
    c = held_out_rays(room.scans, 0.6, 0.05, seed=4)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.train_rays[0], b.train_rays[0])
    assert not np.array_equal(a.train_rays[0], c.train_rays[0])


@pytest.mark.parametrize("fraction", [0.8, 0.4])
def test_split_never_puts_a_ray_in_both_sets(room, fraction):
    (scan,) = room.scans
    resolution = 0.05
    split = held_out_rays(room.scans, fraction, resolution, seed=0)
    (in_train,) = split.train_rays
    assert abs(in_train.mean() - fraction) < 0.01
    np.testing.assert_array_equal(split.train[0].points_world, scan.points_world[in_train])

    held_out = ~in_train
    n_hits = int(scan.hit_mask[held_out].sum())
    occupied, free = split.points[split.occupied], split.points[~split.occupied]
    np.testing.assert_array_equal(occupied, scan.points_world[held_out & scan.hit_mask])
    assert n_hits == split.occupied.sum()
    # One free point per held-out ray, on that ray, at least 2 resolutions before its end.
    offsets = scan.points_world[held_out] - scan.origin
    lengths = np.linalg.norm(offsets, axis=1)
    usable = lengths > 2 * resolution
    assert len(free) == usable.sum()
    along = free - scan.origin
    depth = np.linalg.norm(along, axis=1)
    directions = offsets[usable] / lengths[usable, None]
    np.testing.assert_allclose(along, directions * depth[:, None], atol=1e-9)
    assert np.all(depth <= lengths[usable] - 2 * resolution + 1e-9)
    # No training ray ends where a test hit is.
    train_ends = {tuple(p) for p in split.train[0].points_world}
    assert not any(tuple(p) in train_ends for p in occupied)


def test_split_refuses_fractions_outside_the_unit_interval(room):
    with pytest.raises(ValueError, match="train fraction"):
        held_out_rays(room.scans, 1.0, 0.05, seed=0)


def test_summaries_average_over_seeds():
    def record(seed, f1):
        return EvalRecord("d", "m", 0.8, seed, 0.9, f1, 0.95, 0.0, 1.0, 0.1, 100, 10, 20)

    (summary,) = summarise([record(0, 0.8), record(1, 0.9)])
    assert summary.n_seeds == 2
    assert summary.mean["f1"] == pytest.approx(0.85)
    assert summary.std["f1"] == pytest.approx(np.std([0.8, 0.9], ddof=1))
