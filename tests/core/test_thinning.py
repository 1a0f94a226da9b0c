"""Thinning samples where rays crowd: the compiled kernel against its NumPy twin, and what a
thinned batch keeps."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.samples import training_samples
from ehm.core.scan import Scan
from ehm.core.thinning import thin_samples, thinning_kernel, thinning_keys, thinning_reference


def test_compiled_thinning_matches_reference(rng):
    keys = rng.integers(0, 300, 5_000) * 7919  # spread, with many samples per key
    order = rng.permutation(len(keys))
    keep, share = thinning_kernel(keys, order, 3, 1024)
    want_keep, want_share = thinning_reference(keys, order, 3)
    np.testing.assert_array_equal(keep, want_keep)
    np.testing.assert_array_equal(share, want_share)
    # The first three of each key in the order are kept.
    first = {}
    for i in order:
        first.setdefault(keys[i], []).append(i)
    expected = np.zeros(len(keys), bool)
    expected[[i for rows in first.values() for i in rows[:3]]] = True
    np.testing.assert_array_equal(keep, expected)


@pytest.fixture
def crowded_scan(rng):
    """A 3D scan whose 20,000 rays all start at one sensor: free samples crowd near it."""
    origin = np.array([1.0, -2.0, 0.5])
    directions = rng.normal(size=(20_000, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    return Scan(origin + directions * rng.uniform(2.0, 8.0, (20_000, 1)), origin)


def test_thinning_keeps_at_most_per_cell_and_the_weight_of_each_kind(crowded_scan, rng):
    config = MapConfig(samples_per_cell=4)
    samples = training_samples(crowded_scan, config, rng)
    thinned = thin_samples(samples, config, np.random.default_rng(1))
    assert len(thinned) < 0.7 * len(samples)
    _, per_cell = np.unique(thinning_keys(thinned, config), return_counts=True)
    assert per_cell.max() == 4
    for occupied in (True, False):
        for at_surface in (True, False):
            before = (samples.occupied == occupied) & (samples.at_surface == at_surface)
            after = (thinned.occupied == occupied) & (thinned.at_surface == at_surface)
            assert thinned.weight[after].sum() == pytest.approx(before.sum())
    # Kept samples are samples of the batch, in their order; uncrowded cells keep weight 1.
    index = {tuple(p): i for i, p in enumerate(samples.points)}
    rows = np.array([index[tuple(p)] for p in thinned.points])
    assert np.all(np.diff(rows) > 0)
    assert thinned.weight.min() == 1.0 and thinned.weight.max() > 10.0


def test_thinning_off_keeps_every_sample(crowded_scan, rng):
    config = MapConfig(samples_per_cell=0)
    samples = training_samples(crowded_scan, config, rng)
    assert thin_samples(samples, config, rng) is samples
    np.testing.assert_array_equal(samples.weight, np.ones(len(samples)))


def test_samples_beyond_the_cells_reach_are_named(rng):
    config = MapConfig(samples_per_cell=4)
    scan = Scan(np.array([[0.0, 0.0, 1e6]]), np.zeros(3))
    with pytest.raises(ValueError, match="samples_per_cell=0"):
        thin_samples(training_samples(scan, config, rng), config, rng)
