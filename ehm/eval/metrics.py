"""Classification metrics of occupancy probabilities: accuracy and F1 at 0.5, ROC-AUC."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Scores:
    """accuracy and F1 (occupied class) at threshold 0.5, ROC-AUC, share called unknown."""

    accuracy: float
    f1: float
    auc: float
    unknown: float


def average_ranks(values: np.ndarray) -> np.ndarray:
    """(n,) float64 ranks 1..n of values (n,), ties sharing the mean of their ranks."""
    values = np.asarray(values, dtype=np.float64)
    order = np.argsort(values, kind="stable")
    ordered = values[order]
    starts = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]])
    ends = np.r_[starts[1:], len(values)]
    ranks = np.empty(len(values))
    ranks[order] = np.repeat((starts + 1 + ends) / 2.0, ends - starts)
    return ranks


def roc_auc(labels: np.ndarray, scores: np.ndarray) -> float:
    """Area under the ROC curve; tied scores count one half (Mann-Whitney U)."""
    labels = np.asarray(labels, dtype=bool)
    n_pos, n_neg = int(labels.sum()), int((~labels).sum())
    if n_pos == 0 or n_neg == 0:
        raise ValueError("ROC-AUC needs both occupied and free test points")
    ranks = average_ranks(scores)
    return float((ranks[labels].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def precision_recall(labels: np.ndarray, predicted: np.ndarray) -> tuple[float, float]:
    """Precision and recall of the positive (occupied) class; 0 where undefined (nothing
    predicted, or nothing present)."""
    labels, predicted = np.asarray(labels, dtype=bool), np.asarray(predicted, dtype=bool)
    true_pos = int(np.sum(labels & predicted))
    n_predicted, n_present = int(predicted.sum()), int(labels.sum())
    precision = true_pos / n_predicted if n_predicted else 0.0
    recall = true_pos / n_present if n_present else 0.0
    return precision, recall


def f1_score(labels: np.ndarray, predicted: np.ndarray) -> float:
    """F1 of the positive (occupied) class; 0 when nothing is predicted or present."""
    labels, predicted = np.asarray(labels, dtype=bool), np.asarray(predicted, dtype=bool)
    true_pos = int(np.sum(labels & predicted))
    denominator = int(labels.sum() + predicted.sum())
    return 0.0 if denominator == 0 else 2.0 * true_pos / denominator


def score(
    labels: np.ndarray, probabilities: np.ndarray, unknown: np.ndarray | None = None
) -> Scores:
    """Scores of occupancy probabilities (n,) against boolean labels (n,)."""
    labels = np.asarray(labels, dtype=bool)
    probabilities = np.asarray(probabilities, dtype=np.float64)
    predicted = probabilities > 0.5
    return Scores(
        accuracy=float(np.mean(predicted == labels)),
        f1=f1_score(labels, predicted),
        auc=roc_auc(labels, probabilities),
        unknown=0.0 if unknown is None else float(np.mean(unknown)),
    )
