"""Stage timings."""

import time

import pytest

from ehm.core.timing import StageTimer


def test_stages_add_up_in_the_order_they_first_ran():
    timer = StageTimer()
    with timer("b"):
        time.sleep(0.01)
    with timer("a"):
        pass
    with timer("b"):
        time.sleep(0.01)
    assert list(timer.seconds) == ["b", "a"]
    assert timer.seconds["b"] >= 0.02
    assert timer.total == pytest.approx(sum(timer.seconds.values()))


def test_a_failing_stage_is_timed_too():
    timer = StageTimer()
    with pytest.raises(KeyError), timer("lookup"):
        time.sleep(0.005)
        raise KeyError("x")
    assert timer.seconds["lookup"] >= 0.005
