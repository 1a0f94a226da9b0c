"""The logistic link of Eq. 1: log-odds of occupancy to its probability."""

from __future__ import annotations

import numba
import numpy as np


def sigmoid(log_odds: np.ndarray) -> np.ndarray:
    """p(occupied) = 1 / (1 + exp(-s)) of log-odds s, elementwise, float64."""
    return 1.0 / (1.0 + np.exp(-log_odds))


@numba.njit(cache=True, inline="always")
def sigmoid_scalar(log_odds: float) -> float:  # pragma: no cover - compiled
    """The compiled twin of `sigmoid` for one value, inside compiled loops."""
    return 1.0 / (1.0 + np.exp(-log_odds))
