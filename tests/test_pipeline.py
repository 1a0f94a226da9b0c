"""MappingPipeline: the one scan loop."""

import time

import numpy as np
import pytest

import ehm
from ehm.pipeline import MappingPipeline, NullObserver


class Recorder(NullObserver):
    """Writes down every event it is told of."""

    def __init__(self) -> None:
        self.events: list[tuple] = []

    def started(self, total):
        self.events.append(("started", total))

    def scan_read(self, index, scan):
        self.events.append(("read", index, len(scan)))

    def scan_learned(self, index, scan, hilbert_map):
        self.events.append(("learned", index, hilbert_map.n_scans_))

    def finished(self, run):
        self.events.append(("finished", run.n_scans))


def test_incremental_run_equals_integrating_each_scan(plan):
    recorder = Recorder()
    run = MappingPipeline(plan.scans, ehm.HilbertMap(seed=2), observers=[recorder]).run()
    expected = ehm.HilbertMap(seed=2)
    for scan in plan.scans:
        expected.integrate_scan(scan)
    expected.flush()
    np.testing.assert_array_equal(run.hilbert_map.clusters_.weights, expected.clusters_.weights)
    assert run.n_scans == run.hilbert_map.n_scans_ == len(plan.scans)
    assert run.n_rays == sum(len(s) for s in plan.scans)
    assert len(run.scan_seconds) == len(plan.scans)
    # Each stage is the sum over the scans; reading a list costs next to nothing.
    assert set(run.stage_seconds) == {"read", *expected.timings_}
    assert run.stage_seconds["read"] < 0.01 * sum(run.scan_seconds)
    assert sum(run.stage_seconds.values()) <= run.seconds
    n = len(plan.scans)
    assert recorder.events[0] == ("started", n)
    assert recorder.events[1:3] == [("read", 0, len(plan.scans[0])), ("learned", 0, 1)]
    assert recorder.events[-2:] == [("learned", n - 1, n), ("finished", n)]


def test_incremental_run_learns_the_last_waiting_scans(plan):
    """Scans gathered into batches of 1000 rays (360 each): learned after the third and at the
    end, both times counted with the scan that closed the batch."""
    run = MappingPipeline(plan.scans, ehm.HilbertMap(batch_rays=1000)).run()
    assert run.hilbert_map.n_waiting_scans == 0 and run.n_scans == len(plan.scans)
    expected = ehm.HilbertMap(batch_rays=1000)
    for scan in plan.scans:
        expected.integrate_scan(scan)
    expected.flush()
    np.testing.assert_array_equal(run.hilbert_map.clusters_.weights, expected.clusters_.weights)
    assert len(run.scan_seconds) == len(plan.scans)
    learning = np.argsort(run.scan_seconds)[-2:]
    assert sorted(learning) == [2, 4] and run.batch_scans == [3, 2]
    amortized = run.amortized_scan_seconds()
    np.testing.assert_allclose(amortized[:3], sum(run.scan_seconds[:3]) / 3)
    np.testing.assert_allclose(amortized[3:], sum(run.scan_seconds[3:]) / 2)
    assert run.stage_seconds["sgd"] <= run.scan_seconds[2] + run.scan_seconds[4]


def test_batch_run_fits_once(plan):
    recorder = Recorder()
    scans = (scan for scan in plan.scans)
    run = MappingPipeline(scans, batch=True, observers=[recorder]).run()
    expected = ehm.HilbertMap().fit(plan.scans)
    np.testing.assert_array_equal(run.hilbert_map.clusters_.weights, expected.clusters_.weights)
    assert len(run.scan_seconds) == 1
    # Scans from a generator: the total is not known in advance.
    n = len(plan.scans)
    assert recorder.events == [
        ("started", None),
        *[("read", i, len(s)) for i, s in enumerate(plan.scans)],
        ("finished", n),
    ]


def test_scans_read_lazily_are_timed_as_reading(plan):
    def slowly():
        for scan in plan.scans:
            time.sleep(0.02)
            yield scan

    run = MappingPipeline(slowly()).run()
    assert run.stage_seconds["read"] >= 0.02 * len(plan.scans)
    assert run.n_scans == len(plan.scans)


def test_observers_hear_of_the_end_when_mapping_fails(plan):
    recorder = Recorder()
    pipeline = MappingPipeline([plan.scans[0], "not a scan"], observers=[recorder])
    with pytest.raises(ValueError, match=r"scan 1: expected ehm\.Scan, got str"):
        pipeline.run()
    assert recorder.events[-1] == ("finished", 1)


def test_the_progress_bar_rates_reading_and_learning_apart(plan):
    """Reading a scan takes at least 200 ms here, learning one of 180 rays far less."""
    import io

    from rich.console import Console

    from ehm.pipeline import ProgressBar

    def slow_scans():
        for scan in plan.scans:
            time.sleep(0.2)
            yield scan

    output = io.StringIO()
    bar = ProgressBar(Console(file=output, width=200, force_terminal=False))
    MappingPipeline(slow_scans(), ehm.HilbertMap(batch_rays=0), observers=[bar]).run()
    read, learned = (float(v) for v in _rates(output.getvalue()))
    assert read <= 5.0 < learned


def _rates(text: str) -> tuple[str, str]:
    import re

    found = re.findall(r"read ([\d.]+), learn ([\d.]+) scans/s", text)
    assert found, text
    return found[-1]


def test_observers_are_told_how_many_scans_files_logs_and_bags_hold(plan, plan_log, tmp_path):
    from ehm.eval.guide_files import write_room_bag
    from ehm.io.readers import ScanFiles

    totals = Recorder()
    MappingPipeline(plan.scans, observers=[totals]).run()
    MappingPipeline((s for s in plan.scans), observers=[totals]).run()  # cannot tell
    log = ScanFiles(plan_log, every=2)
    assert len(list(ScanFiles(plan_log))) == 5
    MappingPipeline(log, observers=[totals]).run()
    # The log, read once for its count, gives the same scans as read afresh.
    fresh = list(ScanFiles(plan_log, every=2))
    kept = list(log)
    assert len(kept) == 3 and all(
        np.array_equal(a.points_world, b.points_world) for a, b in zip(kept, fresh, strict=True)
    )
    pytest.importorskip("rosbags")
    write_room_bag(tmp_path / "room.bag", [plan_scan_3d(i) for i in range(4)])
    bag = ScanFiles(tmp_path / "room.bag", topic="/velodyne_points", frame="map", limit=3)
    MappingPipeline(bag, observers=[totals]).run()
    started = [event[1] for event in totals.events if event[0] == "started"]
    assert started == [len(plan.scans), None, 3, 3]


def plan_scan_3d(i: int) -> ehm.Scan:
    """A small 3D scan: 200 hits on a sphere of 3 m around (i, 0, 1)."""
    directions = np.random.default_rng(i).normal(size=(200, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    origin = np.array([float(i), 0.0, 1.0])
    return ehm.Scan(origin + 3.0 * directions, origin)
