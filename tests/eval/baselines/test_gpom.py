"""Gaussian-process occupancy maps."""

import numpy as np
import pytest

from ehm.eval.baselines.gpom import balanced_subsample, plsc_fit


def test_balanced_subsample_takes_half_of_each_class(rng):
    occupied = np.zeros(1000, dtype=bool)
    occupied[:100] = True
    chosen = balanced_subsample(occupied, 120, rng)
    assert len(np.unique(chosen)) == 120 and occupied[chosen].sum() == 60
    chosen = balanced_subsample(occupied, 400, rng)
    assert occupied[chosen].sum() == 100 and len(chosen) == 400
    assert len(balanced_subsample(occupied, 5000, rng)) == 1000


def test_plsc_recovers_a_known_squashing(rng):
    # Labels drawn from p = Phi(2 mu - 0.5) at zero variance: the fit finds a = 2, b = -0.5.
    from scipy.special import ndtr

    mean = rng.uniform(-2, 2, 20_000)
    targets = np.where(rng.random(20_000) < ndtr(2 * mean - 0.5), 1.0, -1.0)
    a, b = plsc_fit(targets, mean, np.zeros_like(mean))
    assert a == pytest.approx(2.0, abs=0.1) and b == pytest.approx(-0.5, abs=0.05)
