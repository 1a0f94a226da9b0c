"""The evaluation runner: plans, runs, records and their summaries."""

import time

import numpy as np
import pytest

from ehm.eval.datasets import DataMissingError
from ehm.eval.runner import EvalRecord, evaluate, plan_evaluation, run_method, summarise


def test_summaries_average_over_seeds():
    def record(seed, f1):
        return EvalRecord("d", "m", 0.8, seed, 0.9, f1, 0.95, 0.0, 1.0, 0.1, 100, 10, 20)

    (summary,) = summarise([record(0, 0.8), record(1, 0.9)])
    assert summary.n_seeds == 2
    assert summary.mean["f1"] == pytest.approx(0.85)
    assert summary.std["f1"] == pytest.approx(np.std([0.8, 0.9], ddof=1))


class SlowMapper:
    """A mapper that takes known times to build and to answer."""

    description = "sleeps"

    def build(self, scans):
        time.sleep(0.03)

    def occupancy(self, points):
        time.sleep(0.01)
        return np.full(len(points), 0.25)

    def memory_bytes(self):
        return 1


def test_run_method_times_build_and_query_apart():
    probability, build_s, query_s = run_method(SlowMapper(), [], np.zeros((4, 3)))
    np.testing.assert_array_equal(probability, 0.25)
    assert 0.03 <= build_s < 0.03 + 0.02 and 0.01 <= query_s < 0.01 + 0.02


def test_plan_checks_names_then_skips_what_is_missing(monkeypatch, tmp_path):
    with pytest.raises(ValueError, match="unknown data set"):
        plan_evaluation(["ehm"], ["kitti"], [0.8])
    with pytest.raises(ValueError, match=r"must be in \(0, 1\), got 1.0"):
        plan_evaluation(["ehm"], ["virtual_room"], [1.0])
    monkeypatch.setenv("EHM_DATA_DIR", str(tmp_path))
    with pytest.raises(DataMissingError, match=r"intel\.gfs\.log not found"):
        plan_evaluation(["ehm"], ["intel_lab"], [0.8])
    plan = plan_evaluation(["hm", "ehm"], ["virtual_room", "intel_lab"], [0.8], skip_missing=True)
    assert list(plan.methods) == ["hm-fourier", "hm-nystrom", "hm-grid", "ehm"]
    assert plan.methods["ehm"].startswith("EHM, incremental")
    assert list(plan.datasets) == ["virtual_room"] and len(plan.datasets["virtual_room"]) == 1
    (message,) = plan.skipped
    assert message.startswith("skipped intel_lab:") and "EHM_DATA_DIR" in message


def test_evaluate_gives_one_record_per_method_fraction_and_seed(room):
    records = evaluate(["virtual_room"], ["ehm", "ehm-batch"], fractions=(0.8, 0.5), seeds=(3,))
    assert [(r.method, r.fraction) for r in records] == [
        ("ehm", 0.8), ("ehm-batch", 0.8), ("ehm", 0.5), ("ehm-batch", 0.5),
    ]  # fmt: skip
    n_rays = len(room.scans[0])
    for record in records:
        assert record.f1 > 0.8 and record.seed == 3
        assert abs(record.n_train / n_rays - record.fraction) < 0.01
    # One scan: both modes learn the same map from the same split.
    assert records[0].f1 == records[1].f1 and records[2].f1 == records[3].f1
