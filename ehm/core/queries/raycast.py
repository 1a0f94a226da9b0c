"""Casting rays through a continuous map: the distance along each ray to the first point whose
log-odds rise above a level, found by marching in even steps and narrowing the step that
crosses.

A map's log-odds on a grid (local grids, Sec. 3.5, far cheaper a point than queries) tell each
ray where to look: `grid_crossings` marches the grid, interpolated, and `refine_guesses`
finds the exact log-odds' crossing around the grid's and narrows it. Rays the grid misleads or
sees no crossing on march the exact log-odds (`first_crossings`). Most of such a ray crosses
space where the log-odds cannot reach the level: a kernel is at most 1, so at any point the
log-odds are at most the intercept plus the sum of the positive weights of the kernels that
reach it. `CandidateCells` keeps the cubic cells where that bound exceeds the
level; a ray walks the cells it crosses (Amanatides & Woo 1987) and marches only through runs
of candidate cells. Marching evaluates many rays at once (STEPS_PER_ROUND points of each
still-running ray in one call of the map's log-odds). A surface thinner than `step` may be
stepped over; the step should be below the thinnest kernel's width.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from ehm.core.primitives.grid_walk import walk_setup, walk_step
from ehm.core.queries.cover import KernelCover, pack_cells, unpack_cells
from ehm.errors import InputError

# Points of every running ray evaluated in one call of the log-odds.
STEPS_PER_ROUND = 32


def checked_rays(
    origins: np.ndarray, directions: np.ndarray, max_range: float | np.ndarray, dim: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays a map of `dim` dimensions can cast: (n, d) origins (given as (n, d) or one (d,)
    point), (n, d) unit directions and (n,) ranges, float64; InputError naming what is
    wrong."""
    directions = np.asarray(directions, dtype=np.float64)
    if directions.ndim != 2 or directions.shape[1] != dim:
        raise InputError(f"ray directions must have shape (n, {dim}), got {directions.shape}")
    origins = np.asarray(origins, dtype=np.float64)
    if origins.shape not in ((dim,), directions.shape):
        raise InputError(
            f"ray origins must have shape ({dim},) or {directions.shape}, got {origins.shape}"
        )
    origins = np.broadcast_to(origins, directions.shape)
    lengths = np.linalg.norm(directions, axis=1)
    if not (np.all(np.isfinite(origins)) and np.all(lengths > 0) and np.all(np.isfinite(lengths))):
        raise InputError("ray origins must be finite and directions finite and not zero")
    max_range = np.broadcast_to(np.asarray(max_range, dtype=np.float64), lengths.shape)
    if not np.all((max_range >= 0) & np.isfinite(max_range)):
        raise InputError("max_range must be finite metres >= 0")
    return np.ascontiguousarray(origins), directions / lengths[:, None], max_range.copy()


def segment_rays(
    starts: np.ndarray, ends: np.ndarray, dim: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segments from starts[i] to ends[i] ((n, d) or one (d,) point each, metres) as rays:
    (n, d) origins, (n, d) directions (any length; ones for a segment of length 0) and (n,)
    lengths, metres; InputError for ends of other shapes."""
    starts, ends = np.atleast_2d(starts).astype(float), np.atleast_2d(ends).astype(float)
    if (
        starts.shape[1:] != (dim,)
        or ends.shape[1:] != (dim,)
        or (len(starts) != len(ends) and 1 not in (len(starts), len(ends)))
    ):
        raise InputError(
            f"segment ends must be (n, {dim}) or ({dim},) points, got {starts.shape} and "
            f"{ends.shape}"
        )
    starts, ends = np.broadcast_arrays(starts, ends)
    lengths = np.linalg.norm(ends - starts, axis=1)
    directions = np.where(lengths[:, None] > 0, ends - starts, 1.0)
    return starts, directions, lengths


def log_odds_level(level: float) -> float:
    """The log-odds of an occupancy probability strictly between 0 and 1; InputError for
    others."""
    if not 0.0 < level < 1.0:
        raise InputError(f"level must be a probability between 0 and 1, got {level}")
    return float(np.log(level / (1.0 - level)))


def unknown_is_obstacle(unknown: str) -> bool:
    """Whether planner queries stop at space without evidence: unknown 'occupied' (their
    default: a planner must not enter what no ray has seen) or 'free'; InputError otherwise."""
    if unknown not in ("occupied", "free"):
        raise InputError(f"unknown must be 'occupied' or 'free', got {unknown!r}")
    return unknown == "occupied"


# How far beyond the grid's crossing a ray looks for the exact one before it marches the exact
# log-odds from its start, in steps of the grid: the grid, interpolated between voxel centres,
# crosses early where a surface is sharper than a voxel.
GUESS_BEHIND_VOXELS = 4.0


def cast_rays(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    max_range: np.ndarray,
    threshold: float,
    voxel: float,
    ray_grid: GridLogOdds | None = None,
    cells: CandidateCells | None = None,
    known: Callable[[np.ndarray], np.ndarray] | None = None,
    known_runs: CandidateCells | None = None,
) -> np.ndarray:
    """(n,) distance, metres, along each ray to the first point where `log_odds` exceeds
    `threshold`, or with `known` to the first point of unknown space where that is nearer
    (stop_at_unknown); inf where neither comes within max_range. Rays march `voxel` / 2
    apart and each crossing is located to `voxel` / 10. With `ray_grid` (voxels of `voxel`
    metres), the exact crossing is looked for from two voxels before the grid's to two after,
    and where none is, on to GUESS_BEHIND_VOXELS after; the other rays march the exact
    log-odds through the runs of `cells` (None: all along)."""
    step, tolerance = voxel / 2.0, voxel / 10.0
    distance = np.full(len(origins), np.nan)
    if ray_grid is not None:
        guess = ray_grid.crossings(origins, directions, max_range, threshold, step)
        guided = np.flatnonzero(np.isfinite(guess))
        reach = max_range[guided]
        distance[guided] = refine_guesses(
            log_odds,
            origins[guided],
            directions[guided],
            np.maximum(guess[guided] - 2.0 * voxel, 0.0),
            np.minimum(guess[guided] + 2.0 * voxel, reach),
            threshold,
            step,
            tolerance,
            np.minimum(guess[guided] + GUESS_BEHIND_VOXELS * voxel, reach),
        )
    rest = np.flatnonzero(np.isnan(distance))
    distance[rest] = first_crossings(
        log_odds,
        origins[rest],
        directions[rest],
        max_range[rest],
        threshold,
        step,
        tolerance,
        cells,
    )
    if known is None:
        return distance
    return stop_at_unknown(
        known, origins, directions, distance, max_range, step, tolerance, known_runs
    )


def stop_at_unknown(
    known: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    distance: np.ndarray,
    max_range: np.ndarray,
    step: float,
    tolerance: float,
    known_runs: CandidateCells | None = None,
) -> np.ndarray:
    """(n,) `distance` along each ray, or the distance to the ray's first point of unknown
    space (`known`, (m, d) points -> (m,) bool, False) where that is nearer: 0 for a ray that
    starts in it. Only the part of each ray before its `distance` (or its max_range) is
    marched, `step` apart, the boundary located within `tolerance`; runs of `known_runs`
    (cells known all through, ehm.core.queries.known_cells) are passed over without a query."""

    def unknown_sign(points: np.ndarray) -> np.ndarray:
        return np.where(known(points), -1.0, 1.0)

    reach = np.where(np.isfinite(distance), distance, max_range)
    if known_runs is None:
        entry = first_crossings(unknown_sign, origins, directions, reach, 0.0, step, tolerance)
        return np.minimum(distance, entry)
    entry = np.full(len(origins), np.inf)
    reached = np.zeros(len(origins))
    active = np.flatnonzero(reach > 0)
    while active.size:
        run_start, run_end = known_runs.next_run(
            origins[active], directions[active], reached[active], reach[active]
        )
        stretch = np.minimum(run_start, reach[active]) - reached[active]
        marched = stretch > 0
        rows = active[marched]
        found = first_crossings(
            unknown_sign,
            origins[rows] + directions[rows] * reached[rows, None],
            directions[rows],
            stretch[marched],
            0.0,
            step,
            tolerance,
        )
        stopped = np.isfinite(found)
        entry[rows[stopped]] = reached[rows[stopped]] + found[stopped]
        # On past the run of known cells, for rays that met one and did not stop before it.
        going = np.isfinite(run_start) & (run_end < reach[active])
        going[np.flatnonzero(marched)[stopped]] = False
        reached[active[going]] = run_end[going]
        active = active[going]
    return np.minimum(distance, entry)


def first_crossings(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    max_range: np.ndarray,
    threshold: float,
    step: float,
    tolerance: float,
    cells: CandidateCells | None = None,
) -> np.ndarray:
    """(n,) distance, metres, along each ray to the first point where `log_odds` (a function of
    (m, d) points) exceeds `threshold`; inf where it does not within the ray's max_range.
    origins (n, d), metres; directions (n, d), unit; max_range (n,), metres. Points are
    `step` apart within the runs of `cells` the ray crosses (None: all along the ray); the
    crossing is located within `tolerance` (the midpoint of the last interval narrowed to it)."""
    n = len(origins)
    distance = np.full(n, np.inf)
    inside = log_odds(origins) > threshold
    distance[inside] = 0.0
    active = np.flatnonzero(~inside & (max_range > 0))
    reached, run_end = np.zeros(n), max_range.copy()
    if cells is not None:
        reached[active], run_end[active] = cells.next_run(
            origins[active], directions[active], reached[active], max_range[active]
        )
        active = active[np.isfinite(reached[active])]
    ladder = step * np.arange(1, STEPS_PER_ROUND + 1)
    while active.size:
        t = np.minimum(reached[active, None] + ladder, run_end[active, None])
        crossed, found, _ = _ladder_crossings(
            log_odds, origins[active], directions[active], reached[active], t, threshold, tolerance
        )
        distance[active[crossed]] = found[crossed]
        active, t = active[~crossed], t[~crossed]
        reached[active] = t[:, -1]
        done = t[:, -1] >= run_end[active]
        if cells is not None and done.any():
            # Past this run of candidate cells: on to the next one, if the ray meets one.
            ended = active[done]
            reached[ended], run_end[ended] = cells.next_run(
                origins[ended], directions[ended], run_end[ended], max_range[ended]
            )
            done[done] = ~np.isfinite(reached[ended])
        active = active[~done]
    return distance


def refine_guesses(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    threshold: float,
    step: float,
    tolerance: float,
    further: np.ndarray | None = None,
) -> np.ndarray:
    """(n,) distance, metres, of the first crossing of `threshold` between `low` and `high`
    (n,) along each ray: samples `step` apart from low, read in one call with low itself, the
    step that crosses narrowed to `tolerance`; NaN where the log-odds are above the threshold
    at low already or never within [low, high] (the guess was wrong). With `further` (n,),
    metres, a ray that stays below the threshold up to high looks on up to further, in a
    second round."""
    distance = np.full(len(low), np.nan)
    rays = (log_odds, origins, directions)
    every = np.arange(len(low))
    below, crossed = _ladder_from(
        *rays, every, low, high, threshold, step, tolerance, distance, from_start=True
    )
    if further is not None:
        on = every[below & ~crossed]
        on = on[further[on] > high[on]]
        _ladder_from(*rays, on, high, further, threshold, step, tolerance, distance)
    return distance


def _ladder_from(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    rays: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    threshold: float,
    step: float,
    tolerance: float,
    distance: np.ndarray,
    from_start: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Sample `rays` (k,) int64 `step` apart from start to end ((n,) metres; the log-odds at
    start at most the threshold, or with from_start read there too, in the same call) and
    write the crossing of those that cross into `distance` (n,); returns ((k,) bool, which
    are below the threshold at start; (k,) bool, which crossed)."""
    count = int(np.ceil(np.max(end[rays] - start[rays], initial=0.0) / step))
    ladder = step * np.arange(0 if from_start else 1, count + 1)
    t = np.minimum(start[rays, None] + ladder, end[rays, None])
    crossed, found, below = _ladder_crossings(
        log_odds, origins[rays], directions[rays], start[rays], t, threshold, tolerance, from_start
    )
    distance[rays[crossed]] = found[crossed]
    return below, crossed


def _ladder_crossings(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    start: np.ndarray,
    t: np.ndarray,
    threshold: float,
    tolerance: float,
    from_start: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays sampled at distances t (n, k), metres, from `start` (n,) on: t's first column is
    start itself when from_start, else beyond it, where the log-odds are known to be at most
    the threshold. Returns (n,) bool, whether a sample is above it (and, from_start, not the
    first: a ray above at its start crosses nowhere); (n,) the crossing narrowed to
    `tolerance` between the first such sample and the one before (or `start`), NaN where none
    is; (n,) bool, whether the log-odds at start are at most the threshold."""
    found = np.full(len(t), np.nan)
    below = np.ones(len(t), dtype=bool)
    if t.size == 0:
        return np.zeros(len(t), dtype=bool), found, below
    above = _above_at(log_odds, origins, directions, t, threshold)
    if from_start:
        below = ~above[:, 0]
        above[~below] = False
    crossed = above.any(axis=1)
    first = np.argmax(above, axis=1)[crossed]
    rows = np.flatnonzero(crossed)
    low = np.where(first > 0, t[rows, np.maximum(first - 1, 0)], start[rows])
    found[rows] = _narrow(
        log_odds, origins[rows], directions[rows], low, t[rows, first], threshold, tolerance
    )
    return crossed, found, below


def _above_at(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    t: np.ndarray,
    threshold: float,
) -> np.ndarray:
    """(n, k) bool: whether the log-odds exceed `threshold` at distances t (n, k), metres,
    ascending along each ray (origins, directions (n, d)), each distance of a row read once: a
    ladder capped at its end repeats it."""
    fresh = np.ones(t.shape, dtype=bool)
    fresh[:, 1:] = t[:, 1:] != t[:, :-1]
    rows, columns = np.nonzero(fresh)
    points = origins[rows] + directions[rows] * t[rows, columns][:, None]
    above = np.zeros(t.shape, dtype=bool)
    above[rows, columns] = log_odds(points) > threshold
    # A repeat reads as the first of its run.
    first = np.maximum.accumulate(np.where(fresh, np.arange(t.shape[1]), 0), axis=1)
    return np.take_along_axis(above, first, axis=1)


# Points an interval that holds a crossing is cut at in one call of the log-odds (at most;
# fewer where fewer reach the tolerance): one call narrows a step of cluster_radius / 2 to
# the tolerance of cluster_radius / 10, which halving the interval took three calls for, each
# of as many points scattered over the rays and so searched alone.
SECTION_POINTS = 4


def _narrow(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    threshold: float,
    tolerance: float,
) -> np.ndarray:
    """Midpoints of intervals [low, high] along rays, log_odds at most the threshold at low
    and above it at high, narrowed until no longer than `tolerance`: each round cuts every
    interval into equal parts (SECTION_POINTS + 1 at most) at points read in one call and
    keeps the first part that crosses."""
    rows = np.arange(len(low))
    while len(low):
        longest = np.max(high - low) / tolerance
        if longest <= 1.0 + 1e-9:
            break
        parts = min(SECTION_POINTS + 1, int(np.ceil(longest - 1e-9)))
        t = low[:, None] + (high - low)[:, None] * (np.arange(1, parts) / parts)
        above = _above_at(log_odds, origins, directions, t, threshold)
        part = np.where(above.any(axis=1), np.argmax(above, axis=1), parts - 1)
        edges = np.column_stack([low, t, high])
        low, high = edges[rows, part], edges[rows, part + 1]
    return 0.5 * (low + high)


def first_crossings_reference(
    log_odds: Callable[[np.ndarray], np.ndarray],
    origins: np.ndarray,
    directions: np.ndarray,
    max_range: np.ndarray,
    threshold: float,
    step: float,
) -> np.ndarray:
    """Plain twin of `first_crossings` without narrowing: every ray sampled `step` apart from
    its origin to its max_range, the first sample above `threshold` (inf where none)."""
    distance = np.full(len(origins), np.inf)
    for i in range(len(origins)):
        t = np.append(np.arange(0.0, max_range[i], step), max_range[i])
        above = log_odds(origins[i] + directions[i] * t[:, None]) > threshold
        if above.any():
            distance[i] = t[np.argmax(above)]
    return distance


@dataclass(frozen=True)
class CandidateCells:
    """Cubic cells of side `side` metres where the log-odds may exceed a threshold: the cells
    a kernel of positive weight reaches (with the intercept, their weights summed, above the
    threshold). keys: (c,) int64, sorted, packed cell coordinates (`bits` per axis, offset by
    2**(bits - 1)); low, high: (d,) int64 corner cells of the box holding them all."""

    side: float
    bits: int
    keys: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def of_kernels(
        cls,
        means: np.ndarray,
        reach: np.ndarray,
        weights: np.ndarray,
        intercept: float,
        threshold: float,
        side: float,
    ) -> CandidateCells | None:
        """From kernel centres (M, d), metres, their reach (M,), metres, and weights (M,):
        None when every cell is a candidate (intercept above the threshold)."""
        return cls.of_cover(
            KernelCover.of_kernels(means, reach, weights, side), intercept, threshold
        )

    @classmethod
    def of_cover(
        cls, cover: KernelCover, intercept: float, threshold: float
    ) -> CandidateCells | None:
        """The cells of `cover` whose summed weight, with the intercept, is above the
        threshold; None when every cell is a candidate (intercept above the threshold)."""
        if intercept > threshold:
            return None
        kept = cover.keys[intercept + cover.sums > threshold]
        return cls.of_keys(kept, cover.side, cover.bits, cover.dim)

    @classmethod
    def of_keys(cls, keys: np.ndarray, side: float, bits: int, dim: int) -> CandidateCells:
        """The cells of sorted packed `keys` ((c,) int64, `bits` an axis) of side `side`."""
        if len(keys) == 0:
            low, high = np.zeros(dim, np.int64), np.full(dim, -1, np.int64)
            return cls(side, bits, keys, low, high)
        coordinates = unpack_cells(keys, bits, dim)
        return cls(side, bits, keys, coordinates.min(axis=0), coordinates.max(axis=0))

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool: whether each of (n, d) points, metres, lies in one of the cells (False
        for rows that are not finite)."""
        with np.errstate(invalid="ignore"):
            cells = np.floor(points / self.side).astype(np.int64)
        inside = np.flatnonzero(
            np.all(np.isfinite(points), axis=1)
            & np.all((cells >= self.low) & (cells <= self.high), axis=1)
        )
        keys = pack_cells(cells[inside], self.bits)
        at = np.minimum(np.searchsorted(self.keys, keys), len(self.keys) - 1)
        found = np.zeros(len(points), dtype=bool)
        found[inside] = self.keys[at] == keys
        return found

    def next_run(
        self, origins: np.ndarray, directions: np.ndarray, start: np.ndarray, stop: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) distances where each ray, from distance `start` on, first enters a candidate
        cell and where that run of candidate cells ends (capped at `stop`); inf, inf where it
        enters none before `stop`."""
        return _next_runs(
            np.ascontiguousarray(origins),
            np.ascontiguousarray(directions),
            np.ascontiguousarray(start, dtype=np.float64),
            np.ascontiguousarray(stop, dtype=np.float64),
            self.keys,
            self.side,
            self.bits,
            self.low,
            self.high,
        )


@numba.njit(cache=True, inline="always")
def _is_candidate(cell, keys, bits):  # pragma: no cover - compiled
    key = 0
    for axis in range(cell.shape[0]):
        key |= (cell[axis] + (1 << (bits - 1))) << (bits * axis)
    at = np.searchsorted(keys, key)
    return at < keys.shape[0] and keys[at] == key


@numba.njit(cache=True, parallel=True)
def _next_runs(
    origins, directions, start, stop, keys, side, bits, low, high
):  # pragma: no cover - compiled
    """See CandidateCells.next_run: a walk through the cells each ray crosses."""
    n, d = origins.shape
    entry = np.full(n, np.inf)
    leave = np.full(n, np.inf)
    for i in numba.prange(n):
        # Clip the ray to the box of candidate cells.
        t0, t1 = start[i], stop[i]
        for a in range(d):
            lo, hi = low[a] * side, (high[a] + 1) * side
            if directions[i, a] == 0.0:
                if origins[i, a] < lo or origins[i, a] >= hi:
                    t1 = -1.0
            else:
                ta = (lo - origins[i, a]) / directions[i, a]
                tb = (hi - origins[i, a]) / directions[i, a]
                t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
        if not t0 < t1:
            continue
        cell = np.empty(d, dtype=np.int64)
        step = np.empty(d, dtype=np.int64)
        next_t = np.empty(d)
        delta = np.empty(d)
        for a in range(d):
            # Nudged along the ray: a ray starting on a cell's far face starts in the next.
            p = origins[i, a] + directions[i, a] * (t0 + 1e-7 * side)
            cell[a] = min(max(np.int64(np.floor(p / side)), low[a]), high[a])
        walk_setup(origins[i], directions[i], side, cell, step, next_t, delta)
        t = t0
        while t < t1:
            if _is_candidate(cell, keys, bits):
                if entry[i] == np.inf:
                    entry[i] = t
            elif entry[i] != np.inf:
                leave[i] = t
                break
            t = walk_step(cell, step, next_t, delta)
        if entry[i] != np.inf and leave[i] == np.inf:
            leave[i] = t1
    return entry, leave


def next_run_reference(
    cells: CandidateCells,
    origins: np.ndarray,
    directions: np.ndarray,
    start: np.ndarray,
    stop: np.ndarray,
    spacing: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of `CandidateCells.next_run`, by sampling each ray `spacing` apart:
    the first sample in a candidate cell and the first one after it that is not."""
    entry, leave = np.full(len(origins), np.inf), np.full(len(origins), np.inf)
    for i in range(len(origins)):
        t = np.arange(start[i], stop[i], spacing)
        cell = np.floor((origins[i] + directions[i] * t[:, None]) / cells.side).astype(np.int64)
        inside = np.all((cell >= cells.low) & (cell <= cells.high), axis=1)
        candidate = inside & np.isin(
            pack_cells(np.where(inside[:, None], cell, 0), cells.bits), cells.keys
        )
        if candidate.any():
            first = int(np.argmax(candidate))
            entry[i] = t[first]
            after = np.flatnonzero(~candidate[first:])
            leave[i] = t[first + after[0]] if len(after) else stop[i]
    return entry, leave


class GridLogOdds(NamedTuple):
    """A map's log-odds at voxel centres: the kernels' summed scores there (d-dimensional,
    float64, C order; the grid's own array, not a copy) plus the `intercept`, the grid's low
    corner `origin` (d,) and voxel side `resolution`, metres."""

    scores: np.ndarray
    intercept: float
    origin: np.ndarray
    resolution: float

    def crossings(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        max_range: np.ndarray,
        threshold: float,
        step: float,
    ) -> np.ndarray:
        """(n,) the first sample along each ray where they exceed `threshold` (grid_crossings,
        of the scores against the threshold less the intercept)."""
        return grid_crossings(
            origins, directions, max_range, self.scores, self.origin, self.resolution,
            threshold - self.intercept, step,
        )  # fmt: skip


@numba.njit(cache=True, parallel=True)
def grid_crossings(
    origins, directions, max_range, scores, grid_origin, resolution, threshold, step
):  # pragma: no cover - compiled
    """(n,) distance of the first sample, `step` apart along each ray from its origin, where
    a grid's log-odds (scores, `d`-dimensional, voxels of `resolution` metres from corner
    grid_origin) interpolated linearly between voxel centres exceed `threshold`; inf where
    none does within max_range. Samples outside the voxel centres' box are not read: no
    crossing is found there."""
    n, d = origins.shape
    shape = np.array(scores.shape)
    flat = scores.ravel()
    strides = np.ones(d, dtype=np.int64)
    for a in range(d - 2, -1, -1):
        strides[a] = strides[a + 1] * shape[a + 1]
    found = np.full(n, np.inf)
    for i in numba.prange(n):
        index = np.empty(d, dtype=np.int64)
        share = np.empty(d)
        t = 0.0
        while t <= max_range[i]:
            inside = True
            for a in range(d):
                f = (origins[i, a] + directions[i, a] * t - grid_origin[a]) / resolution - 0.5
                if not (0.0 <= f < shape[a] - 1):
                    inside = False
                    break
                index[a] = np.int64(f)
                share[a] = f - index[a]
            if inside:
                value = 0.0
                for corner in range(1 << d):
                    weight = 1.0
                    at = 0
                    for a in range(d):
                        if (corner >> a) & 1:
                            weight *= share[a]
                            at += (index[a] + 1) * strides[a]
                        else:
                            weight *= 1.0 - share[a]
                            at += index[a] * strides[a]
                    value += weight * flat[at]
                if value > threshold:
                    found[i] = t
                    break
            t += step
    return found


def grid_crossings_reference(
    origins: np.ndarray,
    directions: np.ndarray,
    max_range: np.ndarray,
    scores: np.ndarray,
    grid_origin: np.ndarray,
    resolution: float,
    threshold: float,
    step: float,
) -> np.ndarray:
    """Plain NumPy twin of `grid_crossings`, with scipy's linear interpolation."""
    from scipy.interpolate import RegularGridInterpolator

    axes = [grid_origin[a] + (np.arange(n) + 0.5) * resolution for a, n in enumerate(scores.shape)]
    interpolate = RegularGridInterpolator(axes, scores, bounds_error=False, fill_value=0.0)
    found = np.full(len(origins), np.inf)
    for i in range(len(origins)):
        t = np.arange(0.0, max_range[i] + 1e-12, step)
        points = origins[i] + directions[i] * t[:, None]
        inside = np.all((points >= [a[0] for a in axes]) & (points < [a[-1] for a in axes]), axis=1)
        above = inside & (interpolate(points) > threshold)
        if above.any():
            found[i] = t[np.argmax(above)]
    return found
