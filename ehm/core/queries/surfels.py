"""The surface of a level of a log-odds grid as small discs (surfels), one per voxel it passes.

A voxel is an obstacle where its log-odds reach the level and the map knows it (some kernel
reaches its centre: |scores| > KNOWN_SCORE), and, when unknown space is taken for occupied,
also where the map does not know it. Every pair of neighbouring voxels (along an axis) of
which one is an obstacle and the other not crosses the surface once: where the log-odds,
linear between the two centres, meet the level when both are known, else half way. Each voxel
with such a crossing on one of its six edges holds one surfel: the mean of its crossings, with
the normal pointing out of the obstacle (towards falling log-odds: minus their gradient by
central differences, or the mean of its edges' directions where that gradient is flat or
points the other way). Grids are 3D; a 2D map's grid is one voxel thick.

Voxel centres can miss an obstacle thinner than a voxel that lies between two of them (a
table top between the centres above and below it). Such an obstacle peaks near the means of
the clusters of positive weight that make it: the log-odds are read there too, and a voxel
holding a mean where they reach the level is an obstacle (`with_peaks`), so it shows.

A grid's log-odds are those of its voxel centres, linear in between only approximately, and
a grid sums every kernel where point queries sum the nearest ones: the surfels are then moved
along their normals to where the map's own log-odds, as point queries read them, meet the
level, or left out where they do not nearby (`on_level`), so that distances agree with
`occupancy`. A map whose point queries search for each point's nearest clusters reads each
surfel's points along its normal from one search around the surfel (`NearLogOdds`), as its
queries in batch mode read a group of points: the searches are most of what putting surfels
on the level costs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numba
import numpy as np

# Voxels whose summed kernel scores are this close to 0 are unknown: no kernel reaches them.
KNOWN_SCORE = 1e-9

# The six neighbours of a voxel.
_STEPS = np.array(
    [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], dtype=np.int64
)


class Surfels(NamedTuple):
    """Surfels of voxels, sorted by key: keys (S,) int64, flat voxel index in the grid's C
    order; positions (S, 3) float64, metres, world frame; normals (S, 3) float64, unit, out of
    the obstacle."""

    keys: np.ndarray
    positions: np.ndarray
    normals: np.ndarray

    @classmethod
    def empty(cls) -> Surfels:
        return cls(np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 3)))

    def outside(self, low: np.ndarray, high: np.ndarray, shape: tuple[int, int, int]) -> Surfels:
        """The surfels of voxels outside the box of voxels [low, high) ((3,) int64)."""
        index = np.column_stack(np.unravel_index(self.keys, shape))
        keep = ~np.all((index >= low) & (index < high), axis=1)
        return Surfels(self.keys[keep], self.positions[keep], self.normals[keep])

    @staticmethod
    def joined(a: Surfels, b: Surfels) -> Surfels:
        """Surfels of two disjoint sets of voxels, sorted by key."""
        keys = np.concatenate([a.keys, b.keys])
        order = np.argsort(keys, kind="stable")
        return Surfels(
            keys[order],
            np.concatenate([a.positions, b.positions])[order],
            np.concatenate([a.normals, b.normals])[order],
        )


# Where on_level looks for the level along a surfel's normal: this many voxels to either side,
# at this many points (odd: one at the surfel), and how many steps then locate it.
LEVEL_SPAN = 1.0
LEVEL_STEPS = 5
LEVEL_REFINEMENTS = 2

ReadNear = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""read(points (n, 3) metres, rows (n,) int64) -> (n,) log-odds: a map's log-odds at points,
each within the spread of the place of its row (see NearLogOdds)."""
NearLogOdds = Callable[[np.ndarray, float], ReadNear]
"""near(places (m, 3) metres, spread metres) -> ReadNear: what reads a map's log-odds around
those places (a map of nearest-cluster features: from one search per place)."""


def anywhere(log_odds: Callable[[np.ndarray], np.ndarray]) -> NearLogOdds:
    """The NearLogOdds of `log_odds` ((n, 3) metres -> (n,)), which reads each point alone."""
    return lambda places, spread: lambda points, rows: log_odds(points)


def with_peaks(
    scores: np.ndarray,
    intercept: float,
    threshold: float,
    peaks: np.ndarray,
    log_odds: Callable[[np.ndarray], np.ndarray],
    origin: np.ndarray,
    resolution: float,
) -> np.ndarray:
    """A copy of `scores` ((X, Y, Z) float64, log-odds less `intercept` at the centres of
    voxels of `resolution` metres from `origin`, (3,) metres) where each voxel holding one of
    `peaks` ((P, 3) metres) at which `log_odds` ((n, 3) metres -> (n,)) reach `threshold`
    takes the largest such log-odds (less the intercept), if larger (see the module)."""
    raised = scores.copy()
    index = np.floor((peaks - origin) / resolution).astype(np.int64)
    inside = np.all((index >= 0) & (index < scores.shape), axis=1)
    if not np.any(inside):
        return raised
    index = index[inside]
    read = log_odds(peaks[inside])
    high = read >= threshold
    np.maximum.at(raised, tuple(index[high].T), read[high] - intercept)
    return raised


def on_level(
    surfels: Surfels,
    near: NearLogOdds,
    threshold: float,
    resolution: float,
) -> Surfels:
    """`surfels` each moved along its normal to the crossing of `threshold` by the log-odds
    `near` reads around it (as point queries read them) nearest its position, within
    LEVEL_SPAN voxels of `resolution` metres to either side: bracketed between LEVEL_STEPS
    points (read from the surfel outwards until one pair brackets a crossing), then located
    by LEVEL_REFINEMENTS steps of false position. Surfels with no crossing there are left
    out: the grid's voxel centres saw a surface the map's own log-odds do not have."""
    count = len(surfels.keys)
    if count == 0:
        return surfels
    read = near(surfels.positions, LEVEL_SPAN * resolution)
    along = np.linspace(-LEVEL_SPAN, LEVEL_SPAN, LEVEL_STEPS) * resolution
    # Read from the middle out: the points nearest the surfel first, then the next pair out
    # only for the surfels whose points read so far bracket no crossing. The crossing nearest
    # the surfel is the same; most surfels need three points, not five.
    above = np.full((count, LEVEL_STEPS), np.nan)
    middle = LEVEL_STEPS // 2
    nearest = np.zeros(count, dtype=np.int64)
    found = np.zeros(count, dtype=bool)
    for half_width in range(1, middle + 1):
        rows = np.flatnonzero(~found)
        if len(rows) == 0:
            break
        outer = [middle - half_width, middle + half_width]
        columns = [middle, *outer] if half_width == 1 else outer
        points = (
            surfels.positions[rows, None, :]
            + along[None, columns, None] * surfels.normals[rows, None, :]
        )
        owners = np.repeat(rows, len(columns))
        values = read(points.reshape(-1, 3), owners).reshape(len(rows), len(columns))
        above[rows[:, None], columns] = values - threshold
        # Crossings out of the obstacle (behind the surfel, against its normal) into free
        # space, in the intervals just opened: the inner one on the side behind first.
        for interval in (middle - half_width, middle + half_width - 1):
            crossing = (above[rows, interval] >= 0.0) & (above[rows, interval + 1] < 0.0)
            fresh = rows[crossing & ~found[rows]]
            nearest[fresh] = interval
            found[fresh] = True
    rows = np.flatnonzero(found)
    start, normals = surfels.positions[rows], surfels.normals[rows]
    # The bracket [inner, outer] along the normal, the level minus the log-odds at its ends.
    inner, outer = along[nearest[rows]], along[nearest[rows] + 1]
    at_inner, at_outer = above[rows, nearest[rows]], above[rows, nearest[rows] + 1]
    for _ in range(LEVEL_REFINEMENTS):
        guess = inner + at_inner / (at_inner - at_outer) * (outer - inner)
        at_guess = read(start + guess[:, None] * normals, rows) - threshold
        inside = at_guess >= 0.0
        inner, at_inner = np.where(inside, guess, inner), np.where(inside, at_guess, at_inner)
        outer, at_outer = np.where(inside, outer, guess), np.where(inside, at_outer, at_guess)
    moved = inner + at_inner / (at_inner - at_outer) * (outer - inner)
    return Surfels(surfels.keys[rows], start + moved[:, None] * normals, normals)


def box_surfels(
    scores: np.ndarray,
    intercept: float,
    threshold: float,
    unknown_is_occupied: bool,
    origin: np.ndarray,
    resolution: float,
    low: np.ndarray,
    high: np.ndarray,
) -> Surfels:
    """The surfels of the voxels in the box [low, high) ((3,) int64) of a grid of `scores`
    (X, Y, Z float64, log-odds less the `intercept`) with voxel (0, 0, 0)'s low corner at
    `origin` ((3,) metres) and sides of `resolution` metres, for the surface where the log-odds
    reach `threshold` (see the module)."""
    shape = np.array(scores.shape)
    # Whether each voxel of the box and of its rim within the grid is an obstacle.
    rim_low, rim_high = np.maximum(low - 1, 0), np.minimum(high + 1, shape)
    obstacle = _obstacles(
        scores, intercept, threshold, unknown_is_occupied, rim_low, rim_high - rim_low
    )
    per_plane = _crossings_per_plane(obstacle, low - rim_low, high - low)
    starts = np.concatenate([[0], np.cumsum(per_plane)])
    keys = np.empty(starts[-1], dtype=np.int64)
    positions, normals = np.empty((starts[-1], 3)), np.empty((starts[-1], 3))
    _box_surfels(
        scores,
        obstacle,
        rim_low,
        intercept,
        threshold,
        origin,
        resolution,
        low,
        high - low,
        starts,
        keys,
        positions,
        normals,
        _STEPS,
    )
    return Surfels(keys, positions, normals)


@numba.njit(cache=True, inline="always")
def is_obstacle(score, intercept, threshold, unknown_is_occupied):  # pragma: no cover - compiled
    """A voxel of `score` (log-odds less `intercept`) is an obstacle (see the module)."""
    if abs(score) <= KNOWN_SCORE:
        return unknown_is_occupied
    return score + intercept >= threshold


@numba.njit(cache=True, parallel=True)
def _obstacles(
    scores, intercept, threshold, unknown_is_occupied, low, box
):  # pragma: no cover - compiled
    """(box) bool: whether each voxel of the box of `box` voxels from `low` ((3,) int64) of
    the grid of `scores` is an obstacle (is_obstacle)."""
    obstacle = np.empty((box[0], box[1], box[2]), dtype=np.bool_)
    for bi in numba.prange(box[0]):
        for bj in range(box[1]):
            for bk in range(box[2]):
                score = scores[low[0] + bi, low[1] + bj, low[2] + bk]
                obstacle[bi, bj, bk] = is_obstacle(score, intercept, threshold, unknown_is_occupied)
    return obstacle


@numba.njit(cache=True, inline="always")
def _crosses(obstacle, i, j, k):  # pragma: no cover - compiled
    """Whether voxel (i, j, k) of `obstacle` differs from one of its six neighbours there."""
    here = obstacle[i, j, k]
    return (
        (i > 0 and obstacle[i - 1, j, k] != here)
        or (i + 1 < obstacle.shape[0] and obstacle[i + 1, j, k] != here)
        or (j > 0 and obstacle[i, j - 1, k] != here)
        or (j + 1 < obstacle.shape[1] and obstacle[i, j + 1, k] != here)
        or (k > 0 and obstacle[i, j, k - 1] != here)
        or (k + 1 < obstacle.shape[2] and obstacle[i, j, k + 1] != here)
    )


@numba.njit(cache=True, parallel=True)
def _crossings_per_plane(obstacle, offset, box):  # pragma: no cover - compiled
    """(box[0],) int64: the voxels of each plane (first axis) of the box of `box` voxels,
    `offset` ((3,) int64) into `obstacle` (the box and its rim in the grid), with a crossing
    on one of their edges."""
    counts = np.zeros(box[0], dtype=np.int64)
    for bi in numba.prange(box[0]):
        for bj in range(box[1]):
            for bk in range(box[2]):
                if _crosses(obstacle, offset[0] + bi, offset[1] + bj, offset[2] + bk):
                    counts[bi] += 1
    return counts


@numba.njit(cache=True, parallel=True)
def _box_surfels(
    scores,
    obstacle,
    rim_low,
    intercept,
    threshold,
    origin,
    resolution,
    low,
    box,
    starts,
    keys,
    positions,
    normals,
    steps,
):  # pragma: no cover - compiled
    """The surfels of the box of `box` voxels from `low` ((3,) int64), plane by plane (first
    axis) from starts[plane] on in keys, positions and normals, in the order of their keys;
    obstacle: is_obstacle of the box and its rim, whose low corner is rim_low."""
    shape = scores.shape
    for bi in numba.prange(box[0]):
        out = starts[bi]
        i = low[0] + bi
        for bj in range(box[1]):
            j = low[1] + bj
            for bk in range(box[2]):
                k = low[2] + bk
                oi, oj, ok = i - rim_low[0], j - rim_low[1], k - rim_low[2]
                if not _crosses(obstacle, oi, oj, ok):
                    continue
                score = scores[i, j, k]
                here = obstacle[oi, oj, ok]
                known_here = abs(score) > KNOWN_SCORE
                n = 0
                px = py = pz = 0.0  # the crossings' offsets from the centre, summed
                ex = ey = ez = 0.0  # the crossing edges' directions out of the obstacle, summed
                for s in range(6):
                    a, b, c = i + steps[s, 0], j + steps[s, 1], k + steps[s, 2]
                    if a < 0 or b < 0 or c < 0 or a >= shape[0] or b >= shape[1] or c >= shape[2]:
                        continue
                    there = obstacle[a - rim_low[0], b - rim_low[1], c - rim_low[2]]
                    if there == here:
                        continue
                    there_score = scores[a, b, c]
                    # t: share of the edge from the obstacle's centre to the crossing.
                    t = 0.5
                    if known_here and abs(there_score) > KNOWN_SCORE:
                        inside = score if here else there_score
                        outside = there_score if here else score
                        t = (inside + intercept - threshold) / (inside - outside)
                        t = min(max(t, 0.0), 1.0)
                    along = (t if here else 1.0 - t) * resolution
                    outward = 1.0 if here else -1.0
                    px += along * steps[s, 0]
                    py += along * steps[s, 1]
                    pz += along * steps[s, 2]
                    ex += outward * steps[s, 0]
                    ey += outward * steps[s, 1]
                    ez += outward * steps[s, 2]
                    n += 1
                keys[out] = (i * shape[1] + j) * shape[2] + k
                positions[out, 0] = origin[0] + (i + 0.5) * resolution + px / n
                positions[out, 1] = origin[1] + (j + 0.5) * resolution + py / n
                positions[out, 2] = origin[2] + (k + 0.5) * resolution + pz / n
                gx = _slope(scores, i, j, k, 0, resolution)
                gy = _slope(scores, i, j, k, 1, resolution)
                gz = _slope(scores, i, j, k, 2, resolution)
                # Minus the gradient where it points out of the obstacle, else the edges' mean.
                if -(gx * ex + gy * ey + gz * ez) > 0.0:
                    norm = -np.sqrt(gx * gx + gy * gy + gz * gz)
                    nx, ny, nz = gx / norm, gy / norm, gz / norm
                else:
                    norm = np.sqrt(ex * ex + ey * ey + ez * ez)
                    if norm == 0.0:  # crossings on opposite faces only: no direction wins
                        norm = 1.0
                    nx, ny, nz = ex / norm, ey / norm, ez / norm
                normals[out, 0] = nx
                normals[out, 1] = ny
                normals[out, 2] = nz
                out += 1


@numba.njit(cache=True, inline="always")
def _slope(scores, i, j, k, axis, resolution):  # pragma: no cover - compiled
    """The scores' central difference along `axis` at voxel (i, j, k), one-sided at the grid's
    faces, per metre; 0 along an axis one voxel thick."""
    at = i if axis == 0 else (j if axis == 1 else k)
    lo, hi = max(at - 1, 0), min(at + 1, scores.shape[axis] - 1)
    if hi == lo:
        return 0.0
    if axis == 0:
        rise = scores[hi, j, k] - scores[lo, j, k]
    elif axis == 1:
        rise = scores[i, hi, k] - scores[i, lo, k]
    else:
        rise = scores[i, j, hi] - scores[i, j, lo]
    return rise / ((hi - lo) * resolution)


def _compressed(
    counts: np.ndarray,
    positions: np.ndarray,
    normals: np.ndarray,
    low: np.ndarray,
    shape: tuple[int, ...],
) -> Surfels:
    """The voxels of a box with a crossing (counts > 0) as Surfels keyed in the whole grid."""
    local = np.flatnonzero(counts.ravel() > 0)
    index = np.column_stack(np.unravel_index(local, counts.shape)) + low
    keys = np.ravel_multi_index(tuple(index.T), shape).astype(np.int64)
    order = np.argsort(keys, kind="stable")
    return Surfels(
        keys[order], positions.reshape(-1, 3)[local][order], normals.reshape(-1, 3)[local][order]
    )


def box_surfels_reference(
    scores: np.ndarray,
    intercept: float,
    threshold: float,
    unknown_is_occupied: bool,
    origin: np.ndarray,
    resolution: float,
    low: np.ndarray,
    high: np.ndarray,
) -> Surfels:
    """Plain NumPy twin of `box_surfels`, one axis of edges at a time."""
    known = np.abs(scores) > KNOWN_SCORE
    obstacle = np.where(known, scores + intercept >= threshold, unknown_is_occupied)
    shape = np.array(scores.shape)
    counts = np.zeros(scores.shape, dtype=np.int64)
    offsets = np.zeros((*scores.shape, 3))
    edges = np.zeros((*scores.shape, 3))
    for axis in range(3):
        first = [slice(None)] * 3
        second = [slice(None)] * 3
        first[axis], second[axis] = slice(0, -1), slice(1, None)
        a, b = tuple(first), tuple(second)
        crossing = obstacle[a] != obstacle[b]
        # t: share of the edge from the obstacle's centre to the crossing
        inside = np.where(obstacle[a], scores[a], scores[b])
        outside = np.where(obstacle[a], scores[b], scores[a])
        both = known[a] & known[b]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.clip((inside + intercept - threshold) / (inside - outside), 0.0, 1.0)
        t = np.where(both, t, 0.5)
        # The voxel before the crossing moves +axis, the one after -axis.
        along_a = np.where(obstacle[a], t, 1.0 - t)
        along_b = np.where(obstacle[b], t, 1.0 - t)
        out_a = np.where(obstacle[a], 1.0, -1.0)
        counts[a] += crossing
        counts[b] += crossing
        offsets[(*a, axis)] += np.where(crossing, along_a * resolution, 0.0)
        offsets[(*b, axis)] -= np.where(crossing, along_b * resolution, 0.0)
        edges[(*a, axis)] += np.where(crossing, out_a, 0.0)
        edges[(*b, axis)] += np.where(crossing, out_a, 0.0)
    gradient = np.zeros((*scores.shape, 3))
    for axis in range(3):
        index = np.arange(shape[axis])
        lo, hi = np.maximum(index - 1, 0), np.minimum(index + 1, shape[axis] - 1)
        span = ((hi - lo) * resolution).astype(float)
        rise = np.take(scores, hi, axis=axis) - np.take(scores, lo, axis=axis)
        view = [None] * 3
        view[axis] = slice(None)
        with np.errstate(divide="ignore", invalid="ignore"):
            gradient[..., axis] = np.where(span[tuple(view)] > 0, rise / span[tuple(view)], 0.0)
    box = tuple(slice(lo, hi) for lo, hi in zip(low, high, strict=True))
    counts, offsets, edges, gradient = counts[box], offsets[box], edges[box], gradient[box]
    centres = np.stack(
        np.meshgrid(
            *(np.arange(lo, hi) + 0.5 for lo, hi in zip(low, high, strict=True)), indexing="ij"
        ),
        axis=-1,
    )
    n = np.maximum(counts, 1)[..., None]
    positions = origin + centres * resolution + offsets / n
    use_gradient = -(gradient * edges).sum(axis=-1) > 0
    gradient_norm = np.linalg.norm(gradient, axis=-1, keepdims=True)
    edge_norm = np.linalg.norm(edges, axis=-1, keepdims=True)
    from_gradient = -gradient / np.where(use_gradient[..., None], gradient_norm, 1.0)
    from_edges = edges / np.where(edge_norm > 0, edge_norm, 1.0)
    normals = np.where(use_gradient[..., None], from_gradient, from_edges)
    return _compressed(counts, positions, normals, np.asarray(low), scores.shape)
