"""The logistic link."""

import numpy as np

from ehm.core.primitives.logistic import sigmoid, sigmoid_scalar


def test_sigmoid_values_and_symmetry():
    log_odds = np.array([-800.0, -2.0, 0.0, np.log(3.0), 800.0])
    with np.errstate(over="ignore"):
        probability = sigmoid(log_odds)
    np.testing.assert_allclose(probability, [0.0, 1 / (1 + np.e**2), 0.5, 0.75, 1.0])
    x = np.linspace(-30, 30, 101)
    np.testing.assert_allclose(sigmoid(x) + sigmoid(-x), 1.0)


def test_compiled_sigmoid_matches_numpy():
    x = np.linspace(-40, 40, 401)
    np.testing.assert_allclose([sigmoid_scalar(v) for v in x], sigmoid(x), rtol=1e-15)
