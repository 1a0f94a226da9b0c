"""Surfels: where a grid's log-odds cross the level, against their NumPy twin, on a ball known
exactly, and moved onto the level of the exact log-odds."""

import numpy as np
from ball_fields import ORIGIN, RESOLUTION, SHAPE, ball_log_odds, centres

from ehm.core.queries.surfels import (
    Surfels,
    anywhere,
    box_surfels,
    box_surfels_reference,
    on_level,
)


def test_surfels_agree_with_their_twin(rng):
    scores = rng.normal(size=(9, 8, 7))
    scores[rng.random(scores.shape) < 0.2] = 0.0  # unknown voxels
    for unknown_is_occupied in (False, True):
        for low, high in [((0, 0, 0), (9, 8, 7)), ((2, 1, 3), (7, 8, 5))]:
            args = (scores, 0.3, 0.1, unknown_is_occupied, ORIGIN, RESOLUTION)
            box = (np.array(low), np.array(high))
            compiled, reference = box_surfels(*args, *box), box_surfels_reference(*args, *box)
            assert len(compiled.keys) > 20
            np.testing.assert_array_equal(compiled.keys, reference.keys)
            np.testing.assert_allclose(compiled.positions, reference.positions, atol=1e-12)
            np.testing.assert_allclose(compiled.normals, reference.normals, atol=1e-12)


def test_surfels_lie_on_a_ball_and_point_out_of_it():
    scores = ball_log_odds(centres())
    surfels = box_surfels(
        scores, 0.0, 0.0, False, ORIGIN, RESOLUTION, np.zeros(3, int), np.array(SHAPE)
    )
    radii = np.linalg.norm(surfels.positions, axis=1)
    outward = np.sum(surfels.normals * surfels.positions, axis=1) / radii
    assert len(radii) > 300
    assert np.abs(radii - 0.45).max() < 0.5 * RESOLUTION
    assert outward.min() > 0.9


def test_on_level_moves_surfels_onto_the_exact_level():
    scores = ball_log_odds(centres())
    surfels = box_surfels(
        scores, 0.0, 0.0, False, ORIGIN, RESOLUTION, np.zeros(3, int), np.array(SHAPE)
    )
    # The map's own log-odds put the surface 3 cm inside the grid's.
    moved = on_level(surfels, anywhere(lambda p: ball_log_odds(p, radius=0.42)), 0.0, RESOLUTION)
    radii = np.linalg.norm(moved.positions, axis=1)
    # Along each normal, within the normal's angle to the radius.
    assert np.median(np.abs(radii - 0.42)) < 2e-3
    np.testing.assert_array_equal(moved.keys, surfels.keys)
    # No crossing within a voxel to either side: the surfel is left out.
    inner = on_level(surfels, anywhere(lambda p: ball_log_odds(p, radius=0.3)), 0.0, RESOLUTION)
    assert len(inner.keys) == 0
    everywhere_occupied = anywhere(lambda p: np.full(len(p), 5.0))
    assert len(on_level(surfels, everywhere_occupied, 0.0, RESOLUTION).keys) == 0


def test_on_level_reads_from_the_surfel_outwards_and_takes_the_nearest_crossing():
    # Three surfels on the x axis, normals along +x, each with the level crossed (in to out)
    # at these offsets: half a voxel holds the first, the second lies beyond it, the third
    # has one crossing on either side, both beyond half a voxel.
    centres_x = np.array([0.0, 1.0, 2.0])
    surfels = Surfels(
        np.arange(3, dtype=np.int64),
        np.column_stack([centres_x, np.zeros(3), np.zeros(3)]),
        np.tile([1.0, 0.0, 0.0], (3, 1)),
    )

    def log_odds(points):
        offset = points[:, 0] - np.round(points[:, 0])
        surfel = np.round(points[:, 0]).astype(int)
        single = np.where(surfel == 0, 0.02, 0.08) - offset
        # The third: inside behind -0.07, out to 0.03, inside again to 0.08, then out.
        double = np.where((offset < -0.07) | ((offset > 0.03) & (offset < 0.08)), 1.0, -1.0)
        return np.where(surfel == 2, double, 20.0 * single)

    asked = []
    counted = anywhere(lambda p: asked.append(len(p)) or log_odds(p))
    moved = on_level(surfels, counted, 0.0, RESOLUTION)
    # Three points for every surfel, then the outer pair for the two the first do not settle.
    assert asked[:2] == [9, 4]
    np.testing.assert_array_equal(moved.keys, [0, 1, 2])
    np.testing.assert_allclose(moved.positions[:2, 0], [0.02, 1.08], atol=1e-12)
    # Of the two crossings as near, the one behind the surfel.
    assert 2.0 - 0.1 <= moved.positions[2, 0] <= 2.0 - 0.05
