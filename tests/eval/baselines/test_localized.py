"""EHM and LLS-HM as Mappers."""

import numpy as np
import pytest

from ehm.eval.baselines.localized import LocalizedMapper


def test_incremental_ehm_times_every_scan_and_batch_learns_at_once(plan):
    incremental, batch = LocalizedMapper("ehm"), LocalizedMapper("ehm-batch")
    incremental.build(plan.scans)
    batch.build(plan.scans)
    assert len(incremental.scan_seconds) == len(plan.scans)
    assert all(seconds > 0 for seconds in incremental.scan_seconds)
    assert incremental.map.n_scans_ == batch.map.n_scans_ == len(plan.scans)
    assert batch.scan_seconds == []
    # The plan's five scans of 360 rays are fewer than a batch's rays: scan by scan gathers
    # them into one batch, the same map as one fit; each alone makes another.
    alone = LocalizedMapper("ehm-alone")
    alone.build(plan.scans)
    points = plan.scans[0].points_world
    np.testing.assert_array_equal(incremental.occupancy(points), batch.occupancy(points))
    assert alone.map.n_clusters != batch.map.n_clusters
    assert incremental.memory_bytes() == incremental.map.memory_bytes()
    np.testing.assert_array_equal(incremental.occupancy(points), incremental.map.occupancy(points))


def test_ehm_alone_learns_scan_by_scan_without_a_memory(plan):
    mapper = LocalizedMapper("ehm-alone")
    mapper.build(plan.scans)
    assert len(mapper.scan_seconds) == len(plan.scans)
    assert not mapper.map.config.keep_evidence and len(mapper.map.model_.memory) == 0


def test_lls_hm_searches_per_point():
    mapper = LocalizedMapper("lls-hm")
    assert mapper.map.config.train_search == "point"
    assert mapper.map.config.query_mode == "exact"
    kinds = "ehm, ehm-alone, ehm-realtime, ehm-batch, lls-hm"
    with pytest.raises(ValueError, match=f"kind must be one of {kinds}"):
        LocalizedMapper("ehm-fast")
