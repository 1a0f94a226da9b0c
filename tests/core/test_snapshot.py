"""Snapshots: read-only copies of a map's kernels."""

import numpy as np
import pytest

import ehm


def test_a_snapshot_is_a_read_only_copy_of_that_moment(plan):
    hilbert_map = ehm.HilbertMap(query_intercept=True).integrate_scan(plan.scans[0])
    snapshot = hilbert_map.snapshot()
    clusters = hilbert_map.clusters_
    assert snapshot.dim == 2 and len(snapshot) == len(clusters)
    np.testing.assert_array_equal(snapshot.weights, clusters.weights)
    np.testing.assert_array_equal(snapshot.transforms, clusters.transforms)
    assert snapshot.intercept == hilbert_map.bias_ != 0.0
    with pytest.raises(ValueError, match="read-only"):
        snapshot.weights[0] = 1.0
    weights = snapshot.weights.copy()
    hilbert_map.integrate_scan(plan.scans[1])
    np.testing.assert_array_equal(snapshot.weights, weights)
    later = hilbert_map.snapshot()
    assert later.lineage is snapshot.lineage and len(later) > len(snapshot)
    hilbert_map.fit(plan.scans)
    assert hilbert_map.snapshot().lineage is not snapshot.lineage
    assert ehm.HilbertMap().integrate_scan(plan.scans[0]).snapshot().intercept == 0.0
