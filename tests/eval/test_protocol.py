"""The held-out-rays protocol."""

import numpy as np
import pytest

from ehm.eval.protocol import held_out_rays


def test_split_is_reproducible_for_a_seed(room):
    a = held_out_rays(room.scans, 0.6, 0.05, seed=3)
    b = held_out_rays(room.scans, 0.6, 0.05, seed=3)
    c = held_out_rays(room.scans, 0.6, 0.05, seed=4)
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.train_rays[0], b.train_rays[0])
    assert not np.array_equal(a.train_rays[0], c.train_rays[0])


@pytest.mark.parametrize("fraction", [0.8, 0.4])
def test_split_never_puts_a_ray_in_both_sets(room, fraction):
    (scan,) = room.scans
    resolution = 0.05
    split = held_out_rays(room.scans, fraction, resolution, seed=0)
    (in_train,) = split.train_rays
    assert abs(in_train.mean() - fraction) < 0.01
    np.testing.assert_array_equal(split.train[0].points_world, scan.points_world[in_train])

    held_out = ~in_train
    n_hits = int(scan.hit_mask[held_out].sum())
    occupied, free = split.points[split.occupied], split.points[~split.occupied]
    np.testing.assert_array_equal(occupied, scan.points_world[held_out & scan.hit_mask])
    assert n_hits == split.occupied.sum()
    # One free point per held-out ray, on that ray, at least 2 resolutions before its end.
    offsets = scan.points_world[held_out] - scan.origin
    lengths = np.linalg.norm(offsets, axis=1)
    usable = lengths > 2 * resolution
    assert len(free) == usable.sum()
    along = free - scan.origin
    depth = np.linalg.norm(along, axis=1)
    directions = offsets[usable] / lengths[usable, None]
    np.testing.assert_allclose(along, directions * depth[:, None], atol=1e-9)
    assert np.all(depth <= lengths[usable] - 2 * resolution + 1e-9)
    # No training ray ends where a test hit is.
    train_ends = {tuple(p) for p in split.train[0].points_world}
    assert not any(tuple(p) in train_ends for p in occupied)


def test_split_refuses_fractions_outside_the_unit_interval(room):
    with pytest.raises(ValueError, match="train fraction"):
        held_out_rays(room.scans, 1.0, 0.05, seed=0)
