"""Signed distances to the surface where a map's occupancy reaches a level (a Euclidean
signed distance field), kept on a grid of its log-odds as the map learns.

The surface is a set of surfels (ehm.core.queries.surfels), one per voxel it passes. Every
voxel keeps the voxel of the surfel nearest its centre (a feature transform, exact between
centres: ehm.core.queries.nearest_sites). A point's distance is the least
distance from it to the surfels that the eight voxel centres around it keep, each surfel a
disc of half a voxel's radius (a flat surface between two surfels reads its plane, not the
dimples between two points). It is positive in free and unknown space, negative inside
obstacles: by the side of the disc's normal the point lies on where it is within
SIGN_FROM_NORMAL voxels of the disc and faces it (lies no farther beside its rim than above
its plane); elsewhere, where a disc's side says little of the point, by the voxel the point
lies in. Its gradient is the unit vector away from that disc, signed alike. Distances are
kept up to `reach` metres: beyond, they read `reach` (negative inside), with gradient 0, so an
update only has to look `reach` beyond the voxels whose log-odds changed.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

from ehm.core.queries.nearest_sites import nearest_sites
from ehm.core.queries.surfels import (
    KNOWN_SCORE,
    NearLogOdds,
    ReadNear,
    Surfels,
    anywhere,
    box_surfels,
    is_obstacle,
    on_level,
    with_peaks,
)

# The radius of each surfel's disc, in voxels.
DISC_RADIUS = 0.5
# Points nearer their surfel than this many voxels take their sign from its normal; the others
# from their voxel.
SIGN_FROM_NORMAL = 2.0


class DistanceField:
    """Signed distances, metres, to the surface where the log-odds of a 3D grid of scores reach
    `threshold` (see the module). origin: (3,) metres, world frame, low corner of voxel
    (0, 0, 0); resolution: voxel side, metres; shape: voxels per axis; unknown_is_occupied:
    voxels no kernel reaches are obstacles too (else free); reach: metres, farthest distance
    kept; unknown_box: (2, 3) metres, world frame, [low, high] corners, or None: with
    unknown_is_occupied, only unknown voxels whose centres lie inside it are obstacles (a
    planner's workspace); obstacle_box, alike: only voxels whose centres lie inside it are
    obstacles, occupied or unknown (a tile's core: beyond it, obstacles are another tile's to
    tell). Fed the grid's scores by `update`; `distances` answers."""

    def __init__(
        self,
        origin: np.ndarray,
        resolution: float,
        shape: tuple[int, int, int],
        threshold: float,
        unknown_is_occupied: bool,
        reach: float,
        unknown_box: np.ndarray | None = None,
        obstacle_box: np.ndarray | None = None,
    ) -> None:
        self.origin = np.asarray(origin, dtype=np.float64)
        self.resolution = float(resolution)
        self.shape = tuple(int(n) for n in shape)
        self.threshold = float(threshold)
        self.unknown_is_occupied = bool(unknown_is_occupied)
        self.reach = float(reach)
        self.unknown_box = None if unknown_box is None else np.asarray(unknown_box, float)
        self.obstacle_box = None if obstacle_box is None else np.asarray(obstacle_box, float)
        self._boxes_unknown = self.unknown_box is not None and self.unknown_is_occupied
        self._boxes = self._boxes_unknown or self.obstacle_box is not None
        self._boxed_scores: np.ndarray | None = None
        # Per voxel: the flat index of the voxel whose surfel is nearest its centre; -1: none.
        self.nearest = np.full(self.shape, -1, dtype=np.int32)
        self.surfels = Surfels.empty()
        self.intercept: float | None = None

    def update(
        self,
        scores: np.ndarray,
        intercept: float,
        log_odds: Callable[[np.ndarray], np.ndarray],
        peaks: np.ndarray,
        changed: np.ndarray | None = None,
        near: NearLogOdds | None = None,
    ) -> None:
        """Follow the grid's new `scores` (the field's shape, float64, log-odds less
        `intercept`) where they changed, in `changed` ((2, 3) int64, the box of voxels [low,
        high); None: everywhere): the surfels of voxels within one voxel of it, found where the
        map's `log_odds` ((n, 3) metres -> (n,), as point queries read them) reach the level at
        one of `peaks` ((P, 3) metres, the means of clusters of positive weight) as well as at
        the voxel centres (ehm.core.queries.surfels.with_peaks) and put on the level of the
        log-odds `near` reads around each surfel (on_level; None: `log_odds`, point by point);
        and the nearest surfels of voxels within `reach` of those."""
        shape = np.array(self.shape)
        if changed is None or intercept != self.intercept:
            changed = np.array([np.zeros(3, dtype=np.int64), shape])
        if np.any(changed[1] <= changed[0]):
            return
        self.intercept = intercept
        near = anywhere(log_odds) if near is None else near
        log_odds, near = self._boxed_readers(log_odds, near, intercept)
        low, high = _grown(changed, 1, shape)  # the voxels whose surfels may change
        seen_low, seen_high = _grown(changed, 2, shape)  # and their neighbours
        seen = tuple(slice(a, b) for a, b in zip(seen_low, seen_high, strict=True))
        corner = self.origin + seen_low * self.resolution
        block = scores[seen]
        if self._boxes:  # the scores as the boxes make them, kept for `distances`
            block = self._boxed(block, corner, intercept)
            if self._boxed_scores is None:  # the first update sees every voxel
                self._boxed_scores = np.empty_like(scores)
            self._boxed_scores[seen] = block
        levels = with_peaks(
            block,
            intercept,
            self.threshold,
            peaks,
            log_odds,
            corner,
            self.resolution,
        )
        local = box_surfels(
            levels,
            intercept,
            self.threshold,
            self.unknown_is_occupied,
            corner,
            self.resolution,
            low - seen_low,
            high - seen_low,
        )
        index = np.column_stack(np.unravel_index(local.keys, levels.shape)) + seen_low
        keys = np.ravel_multi_index(tuple(index.T), self.shape).astype(np.int64)
        fresh = on_level(
            Surfels(keys, local.positions, local.normals), near, self.threshold, self.resolution
        )
        self.surfels = Surfels.joined(self.surfels.outside(low, high, self.shape), fresh)
        margin = int(np.ceil(self.reach / self.resolution)) + 1
        ahead_low, ahead_high = np.maximum(low - margin, 0), np.minimum(high + margin, shape)
        self._nearest_in(ahead_low, ahead_high, margin)

    def _nearest_in(self, low: np.ndarray, high: np.ndarray, margin: int) -> None:
        """Set `nearest` in the box of voxels [low, high) from the surfels within `margin`
        voxels of it (all that can lie within reach of its voxels)."""
        shape = np.array(self.shape)
        seen_low, seen_high = np.maximum(low - margin, 0), np.minimum(high + margin, shape)
        index = np.column_stack(np.unravel_index(self.surfels.keys, self.shape))
        inside = np.all((index >= seen_low) & (index < seen_high), axis=1)
        box = tuple(slice(a, b) for a, b in zip(low, high, strict=True))
        if not np.any(inside):
            self.nearest[box] = -1
            return
        sites = np.zeros(tuple(seen_high - seen_low), dtype=bool)
        sites[tuple((index[inside] - seen_low).T)] = True
        found = nearest_sites(sites, seen_low, shape)
        part = tuple(slice(a, b) for a, b in zip(low - seen_low, high - seen_low, strict=True))
        self.nearest[box] = found[part]

    def distances(
        self, points: np.ndarray, scores: np.ndarray, with_gradient: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) signed distances, metres, at (n, 3) float64 points, metres, world frame, and
        with_gradient their (n, 3) gradients (else (0, 3)); `scores` as last given to
        `update`, for the side of points far from every surfel (with a box, the field's own
        copy as the boxes make them). Points outside the grid lie beyond reach of every
        surfel: reach, or -reach where unknown space is an obstacle (inside the boxes)."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        distance = np.empty(len(points))
        gradient = np.zeros((len(points) if with_gradient else 0, 3))
        if self._boxes:
            scores = self._boxed_scores
        _field_distances(
            points,
            self.origin,
            self.resolution,
            self.nearest,
            self.surfels.keys,
            self.surfels.positions,
            self.surfels.normals,
            DISC_RADIUS * self.resolution,
            self.reach,
            scores,
            self.intercept,
            self.threshold,
            self.unknown_is_occupied,
            distance,
            gradient,
        )
        if self._boxes:  # beyond the grid
            outside = np.zeros(len(points), dtype=bool)
            for box in (self.unknown_box, self.obstacle_box):
                if box is not None:
                    outside |= _outside(points, box)
            distance[outside & (distance == -self.reach)] = self.reach
        return distance, gradient

    def _boxed_readers(
        self, log_odds: Callable[[np.ndarray], np.ndarray], near: NearLogOdds, intercept: float
    ) -> tuple[Callable[[np.ndarray], np.ndarray], NearLogOdds]:
        """`log_odds` and `near` read as `_boxed` reads scores: known and free outside
        obstacle_box, and where no kernel reaches (the log-odds are the `intercept`) outside
        unknown_box."""
        if not self._boxes:
            return log_odds, near
        free = min(self.threshold, intercept) - 1.0

        def boxed(points: np.ndarray, values: np.ndarray) -> np.ndarray:
            unknown = np.abs(values - intercept) <= KNOWN_SCORE
            freed = self._freed(unknown, lambda box: _outside(points, box))
            return np.where(freed, free, values)

        def boxed_near(places: np.ndarray, spread: float) -> ReadNear:
            read = near(places, spread)
            return lambda points, rows: boxed(points, read(points, rows))

        return lambda points: boxed(points, log_odds(points)), boxed_near

    def _boxed(self, scores: np.ndarray, corner: np.ndarray, intercept: float) -> np.ndarray:
        """`scores` (a block of the grid's, its voxel (0, 0, 0) at `corner`, metres) with the
        voxels outside obstacle_box, and the unknown ones outside unknown_box when unknown
        space is an obstacle, made known and free: a copy, or `scores` itself when none
        changes."""
        centres = [
            corner[a] + (np.arange(scores.shape[a]) + 0.5) * self.resolution for a in range(3)
        ]

        def outside(box: np.ndarray) -> np.ndarray:
            inside = [(c >= box[0, a]) & (c <= box[1, a]) for a, c in enumerate(centres)]
            return ~(inside[0][:, None, None] & inside[1][None, :, None] & inside[2][None, None])

        freed = self._freed(np.abs(scores) <= KNOWN_SCORE, outside)
        if not np.any(freed):
            return scores
        free = min(self.threshold - intercept, 0.0) - 1.0  # known, below the level
        return np.where(freed, free, scores)

    def _freed(
        self, unknown: np.ndarray, outside: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        """Which of some voxels or points (`unknown`: bool array, which are unknown) the boxes
        make known and free; outside((2, 3) box) -> bool array: which lie outside it."""
        freed = np.zeros(np.shape(unknown), dtype=bool)
        if self.obstacle_box is not None:
            freed |= outside(self.obstacle_box)
        if self._boxes_unknown:
            freed |= unknown & outside(self.unknown_box)
        return freed

    @property
    def nbytes(self) -> int:
        surfels = self.surfels
        boxed = 0 if self._boxed_scores is None else self._boxed_scores.nbytes
        return self.nearest.nbytes + sum(a.nbytes for a in surfels) + boxed


def _outside(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """(n,) bool: which of (n, 3) points, metres, lie outside `box` ((2, 3) [low, high])."""
    return np.any((points < box[0]) | (points > box[1]), axis=1)


def _grown(box: np.ndarray, voxels: int, shape: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box of voxels [low, high) ((2, 3) int64) grown by `voxels` on every side, within a
    grid of `shape`."""
    return np.maximum(box[0] - voxels, 0), np.minimum(box[1] + voxels, shape)


@numba.njit(cache=True, inline="always")
def _disc_distance(px, py, pz, positions, normals, row, radius):  # pragma: no cover - compiled
    """Distance from a point to surfel `row`'s disc of `radius`, the point's height above its
    plane along the normal, how far beside the disc's rim it lies, and the distance's gradient
    (3 values)."""
    ux = px - positions[row, 0]
    uy = py - positions[row, 1]
    uz = pz - positions[row, 2]
    nx, ny, nz = normals[row, 0], normals[row, 1], normals[row, 2]
    height = ux * nx + uy * ny + uz * nz
    tx, ty, tz = ux - height * nx, uy - height * ny, uz - height * nz
    across = np.sqrt(tx * tx + ty * ty + tz * tz)
    beyond = max(across - radius, 0.0)
    distance = np.sqrt(height * height + beyond * beyond)
    if distance == 0.0:
        return 0.0, height, beyond, nx, ny, nz
    side = beyond / across if beyond > 0.0 else 0.0
    gx = (height * nx + side * tx) / distance
    gy = (height * ny + side * ty) / distance
    gz = (height * nz + side * tz) / distance
    return distance, height, beyond, gx, gy, gz


# Points `_field_distances` answers on one thread at a time.
QUERY_CHUNK = 4096


@numba.njit(cache=True, inline="always")
def _among(values, count, value):  # pragma: no cover - compiled
    """Whether `value` is among the first `count` of `values`."""
    c = 0
    while c < count and values[c] != value:
        c += 1
    return c < count


@numba.njit(cache=True, parallel=True)
def _field_distances(
    points,
    origin,
    resolution,
    nearest,
    keys,
    positions,
    normals,
    radius,
    reach,
    scores,
    intercept,
    threshold,
    unknown_is_occupied,
    distance,
    gradient,
):  # pragma: no cover - compiled
    nx, ny, nz = nearest.shape
    with_gradient = gradient.shape[0] > 0
    count = points.shape[0]
    for chunk in numba.prange((count + QUERY_CHUNK - 1) // QUERY_CHUNK):
        seen = np.empty(8, dtype=np.int64)  # neighbouring voxels mostly keep one surfel
        for n in range(chunk * QUERY_CHUNK, min((chunk + 1) * QUERY_CHUNK, count)):
            ux = (points[n, 0] - origin[0]) / resolution
            uy = (points[n, 1] - origin[1]) / resolution
            uz = (points[n, 2] - origin[2]) / resolution
            if not (0.0 <= ux < nx and 0.0 <= uy < ny and 0.0 <= uz < nz):
                distance[n] = -reach if unknown_is_occupied else reach
                continue
            # The eight voxel centres around the point (repeated at the grid's faces).
            bx, by, bz = int(np.floor(ux - 0.5)), int(np.floor(uy - 0.5)), int(np.floor(uz - 0.5))
            best = np.inf
            best_height = best_beside = 0.0
            gx = gy = gz = 0.0
            for corner in range(8):
                i = min(max(bx + (corner & 1), 0), nx - 1)
                j = min(max(by + ((corner >> 1) & 1), 0), ny - 1)
                k = min(max(bz + ((corner >> 2) & 1), 0), nz - 1)
                key = nearest[i, j, k]
                repeated = _among(seen, corner, key)
                seen[corner] = key
                if key < 0 or repeated:
                    continue
                row = np.searchsorted(keys, key)
                if row == keys.shape[0] or keys[row] != key:
                    continue
                d, height, beside, dx, dy, dz = _disc_distance(
                    points[n, 0], points[n, 1], points[n, 2], positions, normals, row, radius
                )
                if d < best:
                    best, best_height, best_beside = d, height, beside
                    gx, gy, gz = dx, dy, dz
            if best < SIGN_FROM_NORMAL * resolution and abs(best_height) >= best_beside:
                sign = 1.0 if best_height >= 0.0 else -1.0
            else:
                score = scores[int(ux), int(uy), int(uz)]
                sign = (
                    -1.0 if is_obstacle(score, intercept, threshold, unknown_is_occupied) else 1.0
                )
            if best >= reach:
                distance[n] = sign * reach
                continue
            distance[n] = sign * best
            if with_gradient:
                gradient[n, 0] = sign * gx
                gradient[n, 1] = sign * gy
                gradient[n, 2] = sign * gz


def field_distances_reference(
    field: DistanceField, points: np.ndarray, scores: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of `DistanceField.distances` (with gradients)."""
    points = np.asarray(points, dtype=np.float64)
    shape = np.array(field.shape)
    units = (points - field.origin) / field.resolution
    inside_grid = np.all((units >= 0) & (units < shape), axis=1)
    base = np.floor(units - 0.5).astype(np.int64)
    corners = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])
    voxels = np.clip(base[:, None, :] + corners[None], 0, shape - 1)  # (n, 8, 3)
    keys = field.nearest[tuple(np.moveaxis(voxels, -1, 0))].astype(np.int64)  # (n, 8)
    surfels = field.surfels
    if len(surfels.keys) == 0:  # nothing to find: one far surfel that no point takes
        surfels = Surfels(np.array([-1]), np.full((1, 3), np.inf), np.zeros((1, 3)))
    rows = np.minimum(np.searchsorted(surfels.keys, keys), len(surfels.keys) - 1)
    valid = (keys >= 0) & (surfels.keys[rows] == keys)
    offsets = points[:, None, :] - surfels.positions[rows]
    normals = surfels.normals[rows]
    height = np.sum(offsets * normals, axis=-1)
    tangent = offsets - height[..., None] * normals
    across = np.linalg.norm(tangent, axis=-1)
    beyond = np.maximum(across - DISC_RADIUS * field.resolution, 0.0)
    d = np.where(valid, np.hypot(height, beyond), np.inf)
    best = np.argmin(d, axis=1)
    pick = np.arange(len(points))
    nearest_d, nearest_height, beside = d[pick, best], height[pick, best], beyond[pick, best]
    with np.errstate(divide="ignore", invalid="ignore"):
        side = np.where(beyond > 0, beyond / across, 0.0)[pick, best]
        slope = (
            nearest_height[:, None] * normals[pick, best] + side[:, None] * tangent[pick, best]
        ) / nearest_d[:, None]
    slope = np.where((nearest_d == 0)[:, None], normals[pick, best], slope)
    voxel = np.clip(np.floor(units).astype(np.int64), 0, shape - 1)
    score = scores[tuple(voxel.T)]
    obstacle = np.where(
        np.abs(score) <= KNOWN_SCORE,
        field.unknown_is_occupied,
        score + field.intercept >= field.threshold,
    )
    by_normal = (nearest_d < SIGN_FROM_NORMAL * field.resolution) & (
        np.abs(nearest_height) >= beside
    )
    sign = np.where(
        by_normal, np.where(nearest_height >= 0, 1.0, -1.0), np.where(obstacle, -1.0, 1.0)
    )
    sign = np.where(inside_grid, sign, -1.0 if field.unknown_is_occupied else 1.0)
    within = inside_grid & (nearest_d < field.reach)
    distance = sign * np.where(within, nearest_d, field.reach)
    gradient = np.where(within[:, None], sign[:, None] * slope, 0.0)
    return distance, gradient
