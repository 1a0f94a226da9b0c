"""The evaluation runner: records and their summaries."""

import numpy as np
import pytest

from ehm.eval.runner import EvalRecord, summarise


def test_summaries_average_over_seeds():
    def record(seed, f1):
        return EvalRecord("d", "m", 0.8, seed, 0.9, f1, 0.95, 0.0, 1.0, 0.1, 100, 10, 20)

    (summary,) = summarise([record(0, 0.8), record(1, 0.9)])
    assert summary.n_seeds == 2
    assert summary.mean["f1"] == pytest.approx(0.85)
    assert summary.std["f1"] == pytest.approx(np.std([0.8, 0.9], ddof=1))
