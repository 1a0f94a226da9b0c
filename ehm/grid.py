"""Occupancy grids by incremental grid reconstruction (Sec. 3.5, Eq. 17-18).

Each cluster owns a local grid: the voxels of the global grid inside the axis-aligned box
around its kernel's support, the ellipsoid |T_m (x - mu_m)| < 1 (`length_scale` standard
deviations along its eigen-axes, 3 by default) or, for the planar-surface kernel, the box
max_a |(T_m (x - mu_m))_a| < 1 (two standard deviations). Its kernel values there, times its
weight, add into a global score grid s_g = sum_m w_m k(x_g, M_m) (Eq. 17), and p_g =
sigmoid(s_g) (Eq. 18). No neighbour search is needed: the local grids say which kernels reach
a voxel. Kernel values are recomputed when needed rather than stored, which keeps a grid's
memory at its voxels.

A grid remembers the mean, kernel transform and weight each cluster had when it was last
added. `OccupancyGrid.update` takes out the old contribution of every cluster that changed
since, puts in the new one and adds new clusters; when that is more work than starting over,
it rebuilds. A 2D map's grid is computed as a 3D grid one voxel thick, centred on z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from os import PathLike
from typing import TYPE_CHECKING

import numba
import numpy as np

from ehm.kernels import cluster_kernel, cluster_kernel_reference

if TYPE_CHECKING:
    from ehm.model import HilbertMap

# Bytes a grid holds per voxel: float64 scores and float64 probabilities.
BYTES_PER_VOXEL = 16
# Grids that would take more than this are refused before anything is allocated.
DEFAULT_MAX_BYTES = 2**30


@dataclass(frozen=True)
class GridUpdate:
    """What one `OccupancyGrid.update` did: kind 'rebuild' or 'incremental'; local_grids and
    voxels: the local grids it recomputed and the voxels they cover (changed clusters count
    twice: out with the old, in with the new); rebuild_voxels: what a rebuild covers."""

    kind: str
    local_grids: int
    voxels: int
    rebuild_voxels: int


@dataclass(frozen=True)
class _Contributions:
    """Local grids to add into a global grid: lifted to 3D, with their voxel boxes."""

    means: np.ndarray  # (K, 3) metres
    transforms: np.ndarray  # (K, 3, 3) 1/m
    weights: np.ndarray  # (K,)
    planar: np.ndarray  # (K,) bool, planar-surface kernel
    low: np.ndarray  # (K, 3) int64 first voxel of each box
    high: np.ndarray  # (K, 3) int64 last voxel of each box (high < low: empty)

    @property
    def voxels(self) -> int:
        """Voxels the local grids cover in total."""
        return int(np.prod(np.maximum(self.high - self.low + 1, 0), axis=1).sum())


def grid_shape(
    bounds: np.ndarray, resolution: float, dim: int, max_bytes: int = DEFAULT_MAX_BYTES
) -> tuple[np.ndarray, tuple[int, ...]]:
    """Check grid bounds (2, dim) [low corner, high corner], metres, and a resolution, metres;
    return the float64 low corner and the voxels per axis. ValueError for a resolution <= 0,
    bounds of the wrong shape, not finite, inverted or empty, and for grids that would take more
    than `max_bytes` (BYTES_PER_VOXEL per voxel), before anything is allocated."""
    resolution = float(resolution)
    if not np.isfinite(resolution) or resolution <= 0.0:
        raise ValueError(f"grid resolution must be a positive number of metres, got {resolution}")
    expected = f"grid bounds must have shape (2, {dim}), [low corner, high corner]"
    try:
        bounds = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{expected}, got {bounds!r}") from error
    if bounds.shape != (2, dim):
        raise ValueError(f"{expected}, got shape {bounds.shape}")
    if not np.all(np.isfinite(bounds)):
        raise ValueError(f"grid bounds must be finite, got {bounds.tolist()}")
    low, high = bounds
    if np.any(high < low):
        raise ValueError(
            f"grid bounds are inverted: high corner {high.tolist()} lies below low corner "
            f"{low.tolist()} on axis {int(np.argmax(high < low))}"
        )
    if np.any(high == low):
        axis = int(np.argmax(high == low))
        raise ValueError(f"grid bounds are empty: zero extent on axis {axis}")
    counts = np.maximum(np.ceil((high - low) / resolution - 1e-9), 1.0)
    n_bytes = float(np.prod(counts)) * BYTES_PER_VOXEL
    if n_bytes > max_bytes:
        shape = " x ".join(f"{c:.0f}" for c in counts)
        raise ValueError(
            f"a grid of {shape} voxels at {resolution} m would take {n_bytes / 2**30:.2f} GiB, "
            f"more than the limit of {max_bytes / 2**30:.2f} GiB: coarsen the resolution, "
            "shrink the bounds or raise max_bytes"
        )
    return low.copy(), tuple(int(c) for c in counts)


def support_bounds(means: np.ndarray, transforms: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """(2, d) metres: the smallest box holding every kernel's support (all of the map where
    any kernel is non-zero). means: (M >= 1, d) metres; transforms: (M, d, d), 1/m; planar:
    (M,) bool, planar-surface kernels."""
    half = support_half_widths(transforms, planar)
    return np.stack([(means - half).min(axis=0), (means + half).max(axis=0)])


def support_half_widths(transforms: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """(M, d) metres: half-widths of the axis-aligned box around each kernel's support.

    The support {mu + T^-1 u} with |u| < 1 (ball) reaches |row a of T^-1| along world axis a;
    with max_b |u_b| < 1 (box, where `planar`) it reaches the sum of |row a of T^-1|."""
    inverse = np.linalg.inv(transforms)
    return np.where(planar[:, None], np.abs(inverse).sum(axis=2), np.linalg.norm(inverse, axis=2))


class OccupancyGrid:
    """Occupancy probabilities of a map on a regular grid of voxels, 2D or 3D.

    origin: (d,) metres, world frame, low corner of voxel (0, ..., 0). resolution: voxel side,
    metres. shape: voxels per axis. scores: array of `shape`, log-odds w^T phi at each voxel
    centre (Eq. 17); probability: p(occupied) there (Eq. 18). Build one with
    HilbertMap.grid; `update` brings it up to date with the map it came from.
    """

    def __init__(self, origin: np.ndarray, resolution: float, shape: tuple[int, ...]) -> None:
        self.origin = np.asarray(origin, dtype=np.float64)
        self.resolution = float(resolution)
        self.scores = np.zeros(shape)
        self.intercept = 0.0
        self._probability: np.ndarray | None = None
        self._lineage: object | None = None
        self._snapshot: tuple[np.ndarray, ...] | None = None

    @property
    def shape(self) -> tuple[int, ...]:
        return self.scores.shape

    @property
    def dim(self) -> int:
        return self.scores.ndim

    @property
    def bounds(self) -> np.ndarray:
        """(2, d) metres: low and high corner of the grid."""
        return np.stack([self.origin, self.origin + np.array(self.shape) * self.resolution])

    @property
    def probability(self) -> np.ndarray:
        """p(occupied) per voxel, float64 array of `shape` (computed once per update)."""
        if self._probability is None:
            self._probability = 1.0 / (1.0 + np.exp(-(self.scores + self.intercept)))
        return self._probability

    def axis_centers(self, axis: int) -> np.ndarray:
        """(shape[axis],) metres: voxel centres along one axis."""
        return self.origin[axis] + (np.arange(self.shape[axis]) + 0.5) * self.resolution

    def centers(self) -> np.ndarray:
        """(n, d) float64 metres, world frame: voxel centres in `probability.ravel()` order."""
        axes = np.meshgrid(*(self.axis_centers(a) for a in range(self.dim)), indexing="ij")
        return np.column_stack([a.ravel() for a in axes])

    def mesh(self, level: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        """Surface where the probability crosses `level` (marching cubes, 3D grids): vertices
        (V, 3) float64 metres, world frame, and faces (F, 3) int64 vertex rows."""
        from ehm.mesh import marching_cubes

        return marching_cubes(self, level)

    def __repr__(self) -> str:
        shape = " x ".join(str(n) for n in self.shape)
        origin = np.round(self.origin, 3).tolist()
        return f"OccupancyGrid({shape} voxels of {self.resolution} m, origin {origin})"

    # ------------------------------------------------------------ computing
    def update(self, hilbert_map: HilbertMap) -> GridUpdate:
        """Bring the grid up to date with `hilbert_map`: recompute only the local grids of
        clusters whose weight, mean or covariance changed since the last update, of new
        clusters and of clusters merged away, or rebuild when that is less work (or the map
        was refitted or is another)."""
        clusters = hilbert_map.clusters_
        if clusters is None:
            raise RuntimeError("the map is empty: integrate a scan or fit before building a grid")
        if clusters.dim != self.dim:
            raise ValueError(f"the grid is {self.dim}D, the map is {clusters.dim}D")
        current = (clusters.means, clusters.transforms, clusters.weights, clusters.planar_kernel)
        config = hilbert_map.config
        self.intercept = hilbert_map.bias_ if config.query_intercept else 0.0
        self._probability = None
        everything = self._contributions(*current, np.arange(len(clusters)))
        if self._lineage is not hilbert_map._lineage or self._snapshot is None:
            return self._rebuild(hilbert_map, everything, current)
        old_means, old_transforms, old_weights, old_planar = self._snapshot
        n_old, n_new = len(old_weights), len(clusters)
        n_both = min(n_old, n_new)
        # Rows present before and now that differ, rows only before (clusters merged away)
        # and rows only now (new clusters).
        changed = np.flatnonzero(
            (clusters.weights[:n_both] != old_weights[:n_both])
            | np.any(clusters.means[:n_both] != old_means[:n_both], axis=1)
            | np.any(clusters.transforms[:n_both] != old_transforms[:n_both], axis=(1, 2))
            | (clusters.planar_kernel[:n_both] != old_planar[:n_both])
        )
        removed = self._contributions(
            old_means,
            old_transforms,
            -old_weights,
            old_planar,
            np.concatenate([changed, np.arange(n_both, n_old)]),
        )
        added = self._contributions(*current, np.concatenate([changed, np.arange(n_both, n_new)]))
        voxels = removed.voxels + added.voxels
        if voxels >= everything.voxels:
            return self._rebuild(hilbert_map, everything, current)
        accumulate_local_grids(self._scores_3d(), self._origin_3d(), self.resolution, removed)
        accumulate_local_grids(self._scores_3d(), self._origin_3d(), self.resolution, added)
        self._remember(hilbert_map, current)
        n_local = len(removed.weights) + len(added.weights)
        return GridUpdate("incremental", n_local, voxels, everything.voxels)

    def _rebuild(self, hilbert_map, everything: _Contributions, current) -> GridUpdate:
        self.scores[...] = 0.0
        accumulate_local_grids(self._scores_3d(), self._origin_3d(), self.resolution, everything)
        self._remember(hilbert_map, current)
        n_local, voxels = len(everything.weights), everything.voxels
        return GridUpdate("rebuild", n_local, voxels, voxels)

    def _remember(self, hilbert_map: HilbertMap, current) -> None:
        self._lineage = hilbert_map._lineage
        self._snapshot = tuple(a.copy() for a in current)

    def _scores_3d(self) -> np.ndarray:
        return self.scores if self.dim == 3 else self.scores[:, :, None]

    def _origin_3d(self) -> np.ndarray:
        if self.dim == 3:
            return self.origin
        return np.array([self.origin[0], self.origin[1], -0.5 * self.resolution])

    def _contributions(
        self,
        means: np.ndarray,
        transforms: np.ndarray,
        weights: np.ndarray,
        planar: np.ndarray,
        rows: np.ndarray,
    ) -> _Contributions:
        """The local grids of clusters `rows` (weight 0 left out: they add nothing)."""
        rows = rows[weights[rows] != 0.0]
        means, transforms, weights = means[rows], transforms[rows], weights[rows]
        planar = planar[rows]
        half = support_half_widths(transforms, planar) if len(rows) else np.zeros_like(means)
        if self.dim == 2:
            means = np.column_stack([means, np.zeros(len(rows))])
            half = np.column_stack([half, np.zeros(len(rows))])
            lifted = np.zeros((len(rows), 3, 3))
            lifted[:, :2, :2] = transforms
            lifted[:, 2, 2] = 1.0
            transforms = lifted
        origin = self._origin_3d()
        extent = np.array(self._scores_3d().shape) - 1
        # Voxel i's centre is origin + (i + 0.5) resolution; the box holds every centre within
        # `half` of the mean (with a hair of slack for rounding).
        low = np.ceil((means - half - origin) / self.resolution - 0.5 - 1e-9).astype(np.int64)
        high = np.floor((means + half - origin) / self.resolution - 0.5 + 1e-9).astype(np.int64)
        return _Contributions(
            np.ascontiguousarray(means),
            np.ascontiguousarray(transforms),
            np.ascontiguousarray(weights),
            np.ascontiguousarray(planar),
            np.clip(low, 0, None),
            np.minimum(high, extent),
        )


def accumulate_local_grids(
    scores: np.ndarray, origin: np.ndarray, resolution: float, local: _Contributions
) -> None:
    """Add w_m k(x_g, M_m) of every local grid into the (nx, ny, nz) scores in place (Eq. 17).

    Work is split by planes of constant x, so each thread writes its own voxels and the sum at
    a voxel runs over clusters in the same order whatever the number of threads."""
    plane_start, plane_clusters = _clusters_per_plane(local, scores.shape[0])
    _accumulate_planes(
        scores,
        origin,
        resolution,
        local.means,
        local.transforms,
        local.weights,
        local.planar,
        local.low,
        local.high,
        plane_start,
        plane_clusters,
    )


def _clusters_per_plane(local: _Contributions, n_planes: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR lists: the local grids that cross each x-plane, in cluster order."""
    spans = np.maximum(local.high[:, 0] - local.low[:, 0] + 1, 0)
    spans[np.any(local.high < local.low, axis=1)] = 0
    owners = np.repeat(np.arange(len(spans)), spans)
    planes = np.repeat(local.low[:, 0], spans) + (
        np.arange(len(owners)) - np.repeat(np.cumsum(spans) - spans, spans)
    )
    order = np.argsort(planes, kind="stable")
    plane_start = np.concatenate([[0], np.cumsum(np.bincount(planes, minlength=n_planes))])
    return plane_start.astype(np.int64), owners[order].astype(np.int64)


@numba.njit(cache=True, parallel=True)
def _accumulate_planes(
    scores,
    origin,
    resolution,
    means,
    transforms,
    weights,
    planar,
    low,
    high,
    plane_start,
    plane_clusters,
):  # pragma: no cover - compiled
    for i in numba.prange(scores.shape[0]):
        x = origin[0] + (i + 0.5) * resolution
        for e in range(plane_start[i], plane_start[i + 1]):
            m = plane_clusters[e]
            t = transforms[m]
            dx = x - means[m, 0]
            # r^2 = |T d|^2 = d^T A d with A = T^T T; along a row of constant x and y it is a
            # quadratic in dz, so only the voxels where r^2 < bound (plus one) are visited. The
            # ball's bound is 1; the box max_a |u_a| < 1 lies within r^2 < 3.
            bound = 3.0 if planar[m] else 1.0
            a_zz = t[0, 2] * t[0, 2] + t[1, 2] * t[1, 2] + t[2, 2] * t[2, 2]
            for j in range(low[m, 1], high[m, 1] + 1):
                dy = origin[1] + (j + 0.5) * resolution - means[m, 1]
                a0 = t[0, 0] * dx + t[0, 1] * dy
                a1 = t[1, 0] * dx + t[1, 1] * dy
                a2 = t[2, 0] * dx + t[2, 1] * dy
                half_b = a0 * t[0, 2] + a1 * t[1, 2] + a2 * t[2, 2]
                c = a0 * a0 + a1 * a1 + a2 * a2 - bound
                disc = half_b * half_b - a_zz * c
                if disc < 0.0:
                    continue
                root = np.sqrt(disc)
                z_low = means[m, 2] + (-half_b - root) / a_zz - origin[2]
                z_high = means[m, 2] + (-half_b + root) / a_zz - origin[2]
                k_low = max(low[m, 2], int(np.floor(z_low / resolution - 0.5)))
                k_high = min(high[m, 2], int(np.ceil(z_high / resolution - 0.5)))
                for k in range(k_low, k_high + 1):
                    dz = origin[2] + (k + 0.5) * resolution - means[m, 2]
                    p0 = a0 + t[0, 2] * dz
                    p1 = a1 + t[1, 2] * dz
                    p2 = a2 + t[2, 2] * dz
                    r2 = p0 * p0 + p1 * p1 + p2 * p2
                    r_max = max(abs(p0), abs(p1), abs(p2))
                    scores[i, j, k] += weights[m] * cluster_kernel(r2, r_max, planar[m])


def accumulate_local_grids_reference(
    scores: np.ndarray, origin: np.ndarray, resolution: float, local: _Contributions
) -> None:
    """Plain NumPy twin of `accumulate_local_grids`, one local grid at a time."""
    for m in range(len(local.weights)):
        low, high = local.low[m], local.high[m]
        if np.any(high < low):
            continue
        axes = [origin[a] + (np.arange(low[a], high[a] + 1) + 0.5) * resolution for a in range(3)]
        points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1) - local.means[m]
        projected = points @ local.transforms[m].T
        box = tuple(slice(low[a], high[a] + 1) for a in range(3))
        scores[box] += local.weights[m] * cluster_kernel_reference(projected, local.planar[m])


def save_grid(grid: OccupancyGrid, path: str | PathLike[str]) -> None:
    """Write a grid as .npz: probability, scores, intercept, origin, resolution."""
    np.savez_compressed(
        path,
        probability=grid.probability,
        scores=grid.scores,
        intercept=grid.intercept,
        origin=grid.origin,
        resolution=grid.resolution,
    )


def load_grid(path: str | PathLike[str]) -> OccupancyGrid:
    """Read a grid written by save_grid (it no longer follows any map); ValueError for a file
    that lacks its arrays."""
    with np.load(path) as data:
        missing = {"scores", "intercept", "origin", "resolution"} - set(data.files)
        if missing:
            raise ValueError(f"{path}: not an ehm grid file (no {', '.join(sorted(missing))})")
        grid = OccupancyGrid(data["origin"], float(data["resolution"]), data["scores"].shape)
        grid.scores[...] = data["scores"]
        grid.intercept = float(data["intercept"])
    return grid
