"""Signed distance fields: distances against a plane and a ball known exactly, and a field
that follows a changed box against one made from scratch."""

import numpy as np
import pytest
from ball_fields import ORIGIN, RESOLUTION, SHAPE, ball_log_odds, centres

from ehm.core.queries.distance import (
    QUERY_CHUNK,
    DistanceField,
    field_distances_reference,
)
from ehm.core.queries.surfels import (
    Surfels,
    with_peaks,
)

NO_PEAKS = np.zeros((0, 3))


def field_of(
    scores,
    log_odds,
    unknown_is_occupied=False,
    reach=0.6,
    peaks=NO_PEAKS,
    unknown_box=None,
    obstacle_box=None,
):
    field = DistanceField(
        ORIGIN, RESOLUTION, scores.shape, 0.0, unknown_is_occupied, reach, unknown_box, obstacle_box
    )
    field.update(scores, 0.0, log_odds, peaks)
    return field


def test_distances_to_a_ball_are_exact_to_a_few_millimetres(rng):
    scores = ball_log_odds(centres())
    field = field_of(scores, ball_log_odds)
    points = rng.uniform(-0.9, 0.9, (3000, 3))
    distance, gradient = field.distances(points, scores, True)
    exact = np.linalg.norm(points, axis=1) - 0.45
    within = np.abs(exact) < 0.5
    assert np.abs(distance - exact)[within].max() < 0.3 * RESOLUTION
    assert np.median(np.abs(distance - exact)[within]) < 0.004
    # Beyond reach: the reach, signed, and no gradient.
    beyond = np.abs(exact) > 0.65
    np.testing.assert_array_equal(distance[beyond], 0.6 * np.sign(exact[beyond]))
    np.testing.assert_array_equal(gradient[beyond], 0.0)
    # The gradient points away from the ball outside and towards its surface inside alike.
    radial = points / np.linalg.norm(points, axis=1)[:, None]
    cosine = np.sum(gradient * radial, axis=1)
    far_enough = within & (np.abs(exact) > 0.1)
    assert np.median(cosine[far_enough]) > 0.99


def test_compiled_distances_agree_with_their_twin(rng):
    """Points in and around a ball's field, more than the compiled pass answers in one chunk
    (QUERY_CHUNK), and surfels' own places."""
    scores = ball_log_odds(centres())
    scores[:, :, :3] = 0.0  # a slab of unknown space
    for unknown_is_occupied in (False, True):
        field = field_of(scores, ball_log_odds, unknown_is_occupied)
        scattered = rng.uniform(-1.2, 1.2, (2 * QUERY_CHUNK + 500, 3))
        points = np.vstack([scattered, field.surfels.positions[:50]])
        compiled = field.distances(points, scores, True)
        reference = field_distances_reference(field, points, scores)
        np.testing.assert_allclose(compiled[0], reference[0], atol=1e-12)
        np.testing.assert_allclose(compiled[1], reference[1], atol=1e-9)
        # Outside the grid: unknown space, obstacle or not as asked.
        outside = np.abs(points).max(axis=1) >= 1.0
        expected = -0.6 if unknown_is_occupied else 0.6
        np.testing.assert_array_equal(compiled[0][outside], expected)


def test_unknown_space_is_an_obstacle_only_when_asked():
    scores = np.full(SHAPE, -3.0)
    scores[:, :, 10:] = 0.0  # the upper half unknown
    point = np.array([[0.05, 0.05, -0.35]])
    free_field = field_of(scores, lambda p: np.where(p[:, 2] < 0.0, -3.0, 0.0))
    assert free_field.distances(point, scores, False)[0][0] == 0.6
    occupied_field = field_of(scores, lambda p: np.where(p[:, 2] < 0.0, -3.0, 0.0), True)
    assert occupied_field.distances(point, scores, False)[0][0] == pytest.approx(0.35, abs=1e-9)


def test_unknown_space_is_an_obstacle_only_inside_the_box_asked():
    """The upper half unknown, the box reaching 0.3 m into it: unknown space is an obstacle
    from z = 0 to the box's top, and above the box, and beyond the grid, space is free."""
    scores = np.full(SHAPE, -3.0)
    scores[:, :, 10:] = 0.0
    log_odds = lambda p: np.where(p[:, 2] < 0.0, -3.0, 0.0)  # noqa: E731
    box = np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 0.3]])
    field = field_of(scores, log_odds, True, unknown_box=box)
    points = np.array([[0.05, 0.05, -0.35], [0.05, 0.05, 0.45], [0.05, 0.05, 5.0]])
    found = field.distances(points, scores, False)[0]
    assert found[0] == pytest.approx(0.35, abs=1e-9)  # below the unknown, as without a box
    # Above the box: free, 0.15 m above its top, to half a voxel (unknown space reads the
    # level itself, and a surfel on a step of the log-odds is placed to within half a voxel).
    assert 0.15 - 0.05 <= found[1] <= 0.15 + 0.05 + 1e-9
    assert found[2] == 0.6  # outside the grid and the box: free
    everywhere = field_of(scores, log_odds, True, unknown_box=np.array([[-9.0] * 3, [9.0] * 3]))
    np.testing.assert_array_equal(
        everywhere.distances(points[:2], scores, False)[0],
        field_of(scores, log_odds, True).distances(points[:2], scores, False)[0],
    )


def test_only_obstacles_inside_the_obstacle_box_count(rng):
    """The ball cut at x = 0 by the box (a tile's core): its half at x < 0 keeps its sphere,
    the cut is its face, and what lies beyond it, the ball's other half and unknown space, is
    free."""
    box = np.array([[-1.0, -1.0, -1.0], [0.0, 1.0, 1.0]])
    scores = ball_log_odds(centres())
    scores[:, :, 15:] = 0.0  # unknown above z = 0.5
    log_odds = lambda p: np.where(p[:, 2] >= 0.5, 0.0, ball_log_odds(p))  # noqa: E731
    field = field_of(scores, log_odds, True, obstacle_box=box)
    points = np.array(
        [
            [-0.7, 0.05, 0.0],  # 0.25 m from the sphere, within the box
            [0.3, 0.05, 0.0],  # inside the ball beyond the cut: 0.3 m from its face
            [0.7, 0.05, 0.0],  # beyond the ball and the cut
            [0.3, 0.05, 0.8],  # unknown, beyond the cut: 0.3 m from the unknown in the box
            [-0.3, 0.05, 0.8],  # unknown, within the box: inside
            [5.0, 0.05, 0.0],  # beyond the grid and the box: free
        ]
    )
    found = field.distances(points, scores, False)[0]
    # To half a voxel: surfels on a step of the log-odds (the cut, unknown space) are placed
    # to within that.
    np.testing.assert_allclose(found[:4], [0.25, 0.3, 0.6, 0.3], atol=0.5 * RESOLUTION + 1e-9)
    assert found[4] < 0.0 and found[5] == 0.6
    whole = field_of(scores, log_odds, True)  # without the box the ball's other half counts
    assert whole.distances(points[1:3], scores, False)[0][0] < 0.0
    everything = field_of(scores, log_odds, True, obstacle_box=np.array([[-9.0] * 3, [9.0] * 3]))
    inside = rng.uniform(-1.0, 1.0, (2000, 3))
    np.testing.assert_array_equal(
        everything.distances(inside, scores, False)[0], whole.distances(inside, scores, False)[0]
    )


def assert_same_fields(field, fresh, scores, points):
    """A followed field and one made anew of `scores` hold the same surfels and tell the same
    distances at (n, 3) points."""
    np.testing.assert_array_equal(field.surfels.keys, fresh.surfels.keys)
    np.testing.assert_allclose(field.surfels.positions, fresh.surfels.positions, atol=1e-12)
    np.testing.assert_allclose(
        field.distances(points, scores, False)[0],
        fresh.distances(points, scores, False)[0],
        atol=1e-12,
    )


def test_a_field_that_follows_a_changed_box_equals_one_made_anew(rng):
    scores = ball_log_odds(centres())
    field = field_of(scores, ball_log_odds)
    # A second ball arrives in one corner; only its box of voxels changed.
    second = dict(centre=np.array([0.6, 0.6, -0.6]), radius=0.25)

    def both(points):
        first, near = ball_log_odds(points), np.linalg.norm(points - second["centre"], axis=-1)
        return np.where(near < 0.4, np.maximum(first, ball_log_odds(points, **second)), first)

    new_scores = both(centres())
    changed = np.flatnonzero(np.any(new_scores != scores, axis=(1, 2)))
    box = np.array([[9, 9, 0], [20, 20, 11]])
    assert changed.min() >= 9 and np.all(
        np.flatnonzero(np.any(new_scores != scores, axis=(0, 1))) < 11
    )
    field.update(new_scores, 0.0, both, NO_PEAKS, box)
    fresh = field_of(new_scores, both)
    assert_same_fields(field, fresh, new_scores, rng.uniform(-1.0, 1.0, (3000, 3)))


def test_a_boxed_field_that_follows_equals_one_made_anew(rng):
    """The ball, with space above z = 0.5 unknown and an obstacle only below z = 0.75: a second
    ball arrives in a corner, and the followed field and the scores it keeps for the box
    equal those of a field made anew."""
    box = np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 0.75]])

    def unknown_above(log_odds):
        return lambda points: np.where(points[..., 2] >= 0.5, 0.0, log_odds(points))

    first = unknown_above(ball_log_odds)
    scores = first(centres())
    field = field_of(scores, first, True, unknown_box=box)
    second = dict(centre=np.array([0.6, 0.6, -0.6]), radius=0.25)

    def both(points):
        near = np.linalg.norm(points - second["centre"], axis=-1)
        grown = np.maximum(ball_log_odds(points), ball_log_odds(points, **second))
        return np.where(near < 0.4, grown, first(points))

    new_scores = both(centres())
    field.update(new_scores, 0.0, both, NO_PEAKS, np.array([[9, 9, 0], [20, 20, 11]]))
    fresh = field_of(new_scores, both, True, unknown_box=box)
    assert_same_fields(field, fresh, new_scores, rng.uniform(-1.2, 1.2, (3000, 3)))
    # The second ball's centre, 2.5 voxels deep: inside, by its voxel's (kept) score; beyond
    # the box, in unknown space: free.
    inside, above = field.distances(
        np.array([[0.6, 0.6, -0.6], [0.05, 0.05, 0.95]]), new_scores, False
    )[0]
    assert inside == pytest.approx(-0.25, abs=0.02) and above > 0


def thin_slab(points):
    """Log-odds of a slab 4 cm thick between the voxel centres at z = 0.05 and 0.15 m: +2
    for 0.08 <= z <= 0.12, -2 elsewhere (and 0, unknown, nowhere)."""
    z = points[..., 2]
    return np.where((z >= 0.08) & (z <= 0.12), 2.0, -2.0)


def test_an_obstacle_between_voxel_centres_shows_at_its_peaks(rng):
    scores = thin_slab(centres())
    assert np.all(scores < 0)  # every centre misses the slab
    peaks = np.column_stack([rng.uniform(-0.9, 0.9, (40, 2)), np.full(40, 0.1)])
    raised = with_peaks(scores, 0.0, 0.0, peaks, thin_slab, ORIGIN, RESOLUTION)
    voxels = np.floor((peaks - ORIGIN) / RESOLUTION).astype(int)
    np.testing.assert_array_equal(raised[tuple(voxels.T)], 2.0)
    assert np.count_nonzero(raised != scores) == len(np.unique(voxels, axis=0))
    # A peak where the log-odds stay below the level raises nothing.
    low_peak = np.array([[0.0, 0.0, 0.5]])
    np.testing.assert_array_equal(
        with_peaks(scores, 0.0, 0.0, low_peak, thin_slab, ORIGIN, RESOLUTION), scores
    )
    blind = field_of(scores, thin_slab)
    seeing = field_of(scores, thin_slab, peaks=peaks)
    above = np.column_stack([peaks[:, :2], np.full(40, 0.4)])
    assert np.all(blind.distances(above, scores, False)[0] == 0.6)
    # The surfels of the raised voxels go onto the slab's faces (its top, seen from above).
    np.testing.assert_allclose(seeing.distances(above, scores, False)[0], 0.28, atol=0.01)


def test_surfels_of_disjoint_sets_join_sorted():
    a = Surfels(np.array([1, 7]), np.zeros((2, 3)), np.zeros((2, 3)))
    b = Surfels(np.array([3]), np.ones((1, 3)), np.ones((1, 3)))
    joined = Surfels.joined(a, b)
    np.testing.assert_array_equal(joined.keys, [1, 3, 7])
    np.testing.assert_array_equal(joined.positions[1], [1.0, 1.0, 1.0])
    kept = joined.outside(np.array([0, 0, 3]), np.array([1, 1, 4]), (1, 1, 8))
    np.testing.assert_array_equal(kept.keys, [1, 7])
