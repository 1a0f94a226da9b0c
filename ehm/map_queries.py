"""The queries every map answers from its log-odds, written once for HilbertMap and TiledMap:
probabilities, log-odds and their uncertainty, gradients, and for planners rays, segments,
known space and distances."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig
from ehm.core.learned_model import finite_rows
from ehm.core.primitives.logistic import sigmoid
from ehm.core.queries.raycast import (
    checked_rays,
    log_odds_level,
    segment_rays,
    unknown_is_obstacle,
)
from ehm.core.weights.uncertainty import occupancy_std
from ehm.errors import InputError


@dataclass(frozen=True)
class RayQuery:
    """Checked rays, world frame: origins (n, d) and directions (n, d, unit), max_range (n,)
    metres; threshold, the log-odds they stop at; mode, the query mode; stop_at_unknown: they
    stop at unknown space too."""

    origins: np.ndarray
    directions: np.ndarray
    max_range: np.ndarray
    threshold: float
    mode: str
    stop_at_unknown: bool


@dataclass(frozen=True)
class DistanceQuery:
    """A distance query's terms: threshold, the log-odds of obstacles; unknown_is_occupied;
    with_gradient; unknown_box and obstacle_box, (2, d) metres, world frame, or None (see
    MapQueries.distance)."""

    threshold: float
    unknown_is_occupied: bool
    with_gradient: bool
    unknown_box: np.ndarray | None
    obstacle_box: np.ndarray | None


class MapQueries(ABC):
    """Occupancy, probabilities, log-odds, rays and segments of a map whose subclass reads its
    log-odds (`_log_odds`) and casts its rays (`_cast`)."""

    config: MapConfig

    @abstractmethod
    def _query_dim(self, action: str) -> int:
        """The map's axes (2 or 3), after it learned the scans waiting for their batch;
        EmptyMapError naming `action` when it has learned nothing."""

    @abstractmethod
    def _log_odds(
        self, points: np.ndarray, mode: str, with_variance: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) log-odds at (n, d) checked points, metres, world frame, NaN for rows that are
        not finite, and with_variance their (n,) variance (else an empty array)."""

    @abstractmethod
    def _gradient(self, points: np.ndarray, mode: str) -> np.ndarray:
        """`gradient` at (n, d) checked points, metres, world frame."""

    @abstractmethod
    def _known_at(self, points: np.ndarray, mode: str) -> np.ndarray:
        """`known` at (n, d) checked points, metres, world frame."""

    @abstractmethod
    def _distances(self, points: np.ndarray, query: DistanceQuery) -> tuple[np.ndarray, np.ndarray]:
        """`distance` at (n, d) finite points, metres, world frame: (n,) distances and with
        query.with_gradient their (n, d) gradients (else (0, d))."""

    @abstractmethod
    def _cast(self, rays: RayQuery) -> np.ndarray:
        """`raycast` of checked rays."""

    def occupancy(
        self, points: np.ndarray, mode: str | None = None, return_std: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n,) float64 probability that each point is occupied; with return_std, the pair
        (probability, std): std (n,) float64 is the standard deviation of the occupancy
        probability under the weights' Gaussian posterior (ehm.core.weights.uncertainty),
        high where nothing was observed (0.21 with prior_precision 1 and the log-odds read
        raw, more with calibrated ones: MapConfig.calibrate) and shrinking as a place is seen
        again.

        points: (n, d) float, metres, world frame. mode: 'batch' (Alg. 3: one neighbour search
        per group of nearby points) or 'exact' (one per point); default config.query_mode.
        Rows with NaN or infinite coordinates give NaN. A tiled map blends its tiles' answers
        (where no tile learned: 0.5).
        """
        scores, variance = self._log_odds(
            self._checked_points(points), self._mode(mode), return_std
        )
        if not return_std:
            return sigmoid(scores)
        return sigmoid(scores), occupancy_std(scores, variance)

    def predict_proba(
        self, points: np.ndarray, mode: str | None = None, return_std: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n, 2) float64 [p(free), p(occupied)] per point, scikit-learn style; with
        return_std, also the (n,) standard deviation of either (see `occupancy`)."""
        scores, variance = self._log_odds(
            self._checked_points(points), self._mode(mode), return_std
        )
        occupied = sigmoid(scores)
        proba = np.column_stack([1.0 - occupied, occupied])
        return (proba, occupancy_std(scores, variance)) if return_std else proba

    def decision_function(
        self, points: np.ndarray, mode: str | None = None, return_variance: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n,) float64 log-odds of occupancy: w^T phi(x), plus the intercept b when
        config.query_intercept is set (Alg. 3), times the map's calibration scale with
        config.calibrate (ehm.core.weights.calibration); with return_variance, the pair (log-odds,
        variance): (n,) float64 variance of the log-odds under the weights' posterior, from
        which `occupancy`'s std follows (ehm.core.weights.uncertainty.occupancy_std)."""
        checked = self._checked_points(points)
        scores, variance = self._log_odds(checked, self._mode(mode), return_variance)
        return (scores, variance) if return_variance else scores

    def gradient(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n, d) float64 gradient of the occupancy log-odds (`decision_function`) with
        respect to position, 1/m, world frame, at (n, d) points, metres: it points toward more
        occupied space, and p(1 - p) times it is the gradient of the probability. Over the
        same kernels as `decision_function` in `mode`; planar-surface kernels are flat (0 or
        1) and add nothing (ehm.core.queries.gradient); a tiled map adds each tile's log-odds
        times the gradient of its blending weight. NaN rows where points are not finite."""
        return self._gradient(self._checked_points(points), self._mode(mode))

    def known(self, points: np.ndarray, mode: str | None = None) -> np.ndarray:
        """(n,) bool: True where the map has evidence at each of (n, d) points, metres, world
        frame: some cluster's kernel reaches it (clusters form where scans gave samples, free
        and occupied); False where none does (no ray came near: occupancy reads 0.5 there, std
        the prior's) and for rows that are not finite. Planner queries stop there unless
        asked not to (`raycast`, `segment_free`). A tiled map asks the tiles that weigh in
        the blend at each point."""
        return self._known_at(self._checked_points(points), self._mode(mode))

    def distance(
        self,
        points: np.ndarray,
        level: float = 0.5,
        return_gradient: bool = False,
        unknown: str = "occupied",
        unknown_box: np.ndarray | None = None,
        obstacle_box: np.ndarray | None = None,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """(n,) signed Euclidean distance, metres, from each of (n, d) points (metres, world
        frame) to the nearest point whose occupancy is at or above `level`: positive outside,
        negative inside; with return_gradient, also its (n, d) gradient (unit vectors away
        from the nearest obstacle; 0 beyond reach). Distances are kept up to
        config.distance_reach: farther points read that. Unknown space (no kernel reaches it)
        is an obstacle, as raycast and segment_free stop at it (unknown="occupied"), or free
        (unknown="free"); unknown_box, (2, d) metres [low, high] corners, world frame, makes
        it an obstacle only inside that box (a planner's workspace); obstacle_box, alike,
        counts obstacles (occupied, and unknown when asked) only inside it.

        Read from a signed distance field of surfels on cluster_radius voxels, put where the
        log-odds meet the level as point queries read them (ehm.core.queries.distance,
        ehm.grid.planner_support), made on the first call for a level and boxes and kept up
        to date as the map learns (each update's stage 'grids', which on large maps learned
        scan by scan can cost more than the update itself). A tiled map asks each tile of
        the obstacles in its core; the nearest wins, and a point inside any obstacle is
        inside (the deepest wins). NaN rows for points that are not finite; InputError for
        a box of another shape or with low > high, and for maps whose grid would be too
        large to keep (tile them)."""
        points = self._checked_points(points, "measure distances in it")
        finite, query = finite_rows(points)
        found, gradient = self._distances(
            query,
            DistanceQuery(
                log_odds_level(level),
                unknown_is_obstacle(unknown),
                return_gradient,
                checked_box("unknown_box", unknown_box, points.shape[1]),
                checked_box("obstacle_box", obstacle_box, points.shape[1]),
            ),
        )
        distance = np.full(len(points), np.nan)
        distance[finite] = found
        if not return_gradient:
            return distance
        gradients = np.full(points.shape, np.nan)
        gradients[finite] = gradient
        return distance, gradients

    def raycast(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        max_range: float | np.ndarray,
        level: float = 0.5,
        mode: str | None = None,
        unknown: str = "occupied",
    ) -> np.ndarray:
        """(n,) distance, metres, along each ray to the first point whose occupancy rises
        above `level`, or with unknown 'occupied' (the default) to the first point of unknown
        space (see `known`) where that is nearer, as OctoMap's castRay stops there; inf where
        neither comes within `max_range`. origins: (n, d) or one (d,) point, metres, world
        frame; directions: (n, d), any length but 0; max_range: metres, one for all rays or
        (n,). Rays march cluster_radius / 2 apart and each crossing is located to
        cluster_radius / 10 (ehm.core.queries.raycast.cast_rays); a HilbertMap guides them
        by a grid of its log-odds, kept up to date as it learns (each update's stage 'grids',
        ehm.grid.planner_support). A ray starting inside reads 0. With unknown 'free',
        unknown space reads as its occupancy, 0.5: it stops no ray at the default level."""
        dim = self._query_dim("cast rays through it")
        stop = unknown_is_obstacle(unknown)
        origins, directions, max_range = checked_rays(origins, directions, max_range, dim)
        threshold = log_odds_level(level)
        return self._cast(
            RayQuery(origins, directions, max_range, threshold, self._mode(mode), stop)
        )

    def segment_free(
        self,
        starts: np.ndarray,
        ends: np.ndarray,
        level: float = 0.5,
        mode: str | None = None,
        unknown: str = "occupied",
    ) -> np.ndarray:
        """(n,) bool: True where no point of the segment from starts[i] to ends[i] ((n, d) or
        one (d,) point each, metres, world frame) has occupancy above `level`, as `raycast`
        finds it; with unknown 'occupied' (the default), nor lies in unknown space (see
        `known`): never-seen space is never free. unknown 'free' lets segments cross it."""
        starts, directions, lengths = segment_rays(starts, ends, self._query_dim("query it"))
        return np.isinf(self.raycast(starts, directions, lengths, level, mode, unknown))

    def _checked_points(self, points: np.ndarray, action: str = "query it") -> np.ndarray:
        """(n, d) float64 query points; InputError for another shape, EmptyMapError naming
        `action` for an empty map."""
        dim = self._query_dim(action)
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != dim:
            raise InputError(f"query points must have shape (n, {dim}), got {tuple(points.shape)}")
        return points

    def _mode(self, mode: str | None) -> str:
        """`mode`, default config.query_mode; InputError for another than 'batch' or 'exact'."""
        mode = mode or self.config.query_mode
        if mode not in ("batch", "exact"):
            raise InputError(f"query mode must be 'batch' or 'exact', got {mode!r}")
        return mode


def checked_box(name: str, box: np.ndarray | None, dim: int) -> np.ndarray | None:
    """A (2, dim) float64 box of [low, high] corners, metres, or None; InputError naming
    `name` for another shape, NaN or low > high."""
    if box is None:
        return None
    box = np.asarray(box, dtype=np.float64)
    if box.shape != (2, dim):
        raise InputError(f"{name} must have shape (2, {dim}), got {box.shape}")
    if np.isnan(box).any() or np.any(box[0] > box[1]):
        raise InputError(
            f"{name} must be [low corner, high corner] with low <= high and no NaN, "
            f"got {box.tolist()}"
        )
    return box
