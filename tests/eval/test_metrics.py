"""Metrics against hand-computed values."""

import numpy as np
import pytest

from ehm.eval.metrics import average_ranks, f1_score, precision_recall, roc_auc, score


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


def test_precision_and_recall_by_hand():
    labels = np.array([1, 1, 0, 0, 1], dtype=bool)
    predicted = np.array([1, 0, 1, 0, 1], dtype=bool)
    # TP 2, FP 1, FN 1
    assert precision_recall(labels, predicted) == pytest.approx((2 / 3, 2 / 3))
    assert precision_recall(labels, np.zeros(5, bool)) == (0.0, 0.0)
    assert precision_recall(np.zeros(2, bool), np.array([True, False])) == (0.0, 0.0)
