"""Local grids (Sec. 3.5, Eq. 17): each cluster's weighted kernel over the voxels its support
covers, added into a global score grid s_g = sum_m w_m k(x_g, M_m), and, for the occupancy's
uncertainty, into the sums sum_m k(x_g, M_m)^2 / lambda_m and sum_m k(x_g, M_m) (see
ehm.core.weights.uncertainty).

A cluster's local grid is the box of voxels around its kernel's support, the ellipsoid
|T_m (x - mu_m)| < 1 (`length_scale` standard deviations along its eigen-axes, 3 by default)
or, for the planar-surface kernel, the box max_a |(T_m (x - mu_m))_a| < 1 (two standard
deviations). No neighbour search is needed: the local grids say which kernels reach a voxel.
Everything is computed in 3D; a 2D grid is one voxel thick, centred on z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.core.model.kernels import (
    cluster_kernel_reference,
    kernel_code,
    kernels_of_codes_serial,
    support_half_widths,
)
from ehm.core.snapshot import MapSnapshot

# The power of the kernel each field sums: field f of a grid adds up c_mf k(x_g, M_m)^p_f,
# with c_m = (w_m, 1 / lambda_m, 1): the scores, then the two sums of the variance.
FIELD_POWERS = (1, 2, 1)


@dataclass(frozen=True)
class Lattice:
    """Voxel centres origin + (i + 0.5) resolution for 0 <= i < shape, in 3D. origin: (3,)
    metres, world frame; resolution: metres; shape: voxels per axis."""

    origin: np.ndarray
    resolution: float
    shape: tuple[int, int, int]

    @classmethod
    def lift(cls, origin: np.ndarray, resolution: float, shape: tuple[int, ...]) -> Lattice:
        """The lattice of a 2D or 3D grid: origin (d,) metres, shape (d,) voxels."""
        if len(shape) == 3:
            return cls(np.asarray(origin, dtype=np.float64), resolution, tuple(shape))
        lifted = np.array([origin[0], origin[1], -0.5 * resolution])
        return cls(lifted, resolution, (shape[0], shape[1], 1))


@dataclass(frozen=True)
class LocalGrids:
    """Local grids of K clusters on a lattice: means (K, 3) metres; transforms (K, 3, 3) 1/m;
    coefficients (K, C) float64, what each cluster's kernel is multiplied by in each field
    (see `accumulate_local_grids`); planar (K,) bool, planar-surface kernel; low, high (K, 3)
    int64, first and last voxel of each box (high < low on an axis: empty)."""

    means: np.ndarray
    transforms: np.ndarray
    coefficients: np.ndarray
    planar: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def of(
        cls,
        snapshot: MapSnapshot,
        rows: np.ndarray,
        lattice: Lattice,
        sign: float = 1.0,
        with_variance: bool = False,
    ) -> LocalGrids:
        """The local grids of the snapshot's clusters `rows` (int64), with coefficients times
        `sign`: the weights, and with_variance, 1 / precision and 1. Without the variance,
        clusters of weight 0 are left out (they add nothing)."""
        if not with_variance:
            rows = rows[snapshot.weights[rows] != 0.0]
        means, transforms = snapshot.means[rows], snapshot.transforms[rows]
        planar = snapshot.planar_kernel[rows]
        half = support_half_widths(transforms, planar) if len(rows) else np.zeros_like(means)
        if snapshot.dim == 2:
            means = np.column_stack([means, np.zeros(len(rows))])
            half = np.column_stack([half, np.zeros(len(rows))])
            lifted = np.zeros((len(rows), 3, 3))
            lifted[:, :2, :2] = transforms
            lifted[:, 2, 2] = 1.0
            transforms = lifted
        origin, resolution = lattice.origin, lattice.resolution
        # Voxel i's centre is origin + (i + 0.5) resolution; the box holds every centre within
        # `half` of the mean (with a hair of slack for rounding).
        low = np.ceil((means - half - origin) / resolution - 0.5 - 1e-9).astype(np.int64)
        high = np.floor((means + half - origin) / resolution - 0.5 + 1e-9).astype(np.int64)
        coefficients = [snapshot.weights[rows]]
        if with_variance:
            coefficients += [1.0 / snapshot.precision[rows], np.ones(len(rows))]
        return cls(
            np.ascontiguousarray(means),
            np.ascontiguousarray(transforms),
            sign * np.column_stack(coefficients),
            np.ascontiguousarray(planar),
            np.clip(low, 0, None),
            np.minimum(high, np.array(lattice.shape) - 1),
        )

    def __len__(self) -> int:
        return len(self.coefficients)

    @property
    def voxels(self) -> int:
        """Voxels the local grids cover in total."""
        return int(np.prod(np.maximum(self.high - self.low + 1, 0), axis=1).sum())


def accumulate_local_grids(fields: np.ndarray, lattice: Lattice, local: LocalGrids) -> None:
    """Add every local grid into `fields` ((C,) + lattice.shape float64) in place: field f
    sums c_mf k(x_g, M_m)^p_f, with p_f from FIELD_POWERS (field 0: the scores of Eq. 17).
    local has C coefficients per cluster.

    Work is split by planes of constant x, so each thread writes its own voxels and the sum at
    a voxel runs over clusters in the same order whatever the number of threads."""
    plane_start, plane_clusters = _clusters_per_plane(local, fields.shape[1])
    _accumulate_planes(
        fields,
        lattice.origin,
        lattice.resolution,
        local.means,
        local.transforms,
        local.coefficients,
        np.array(FIELD_POWERS[: len(fields)]),
        local.planar,
        local.low,
        local.high,
        plane_start,
        plane_clusters,
    )


def _clusters_per_plane(local: LocalGrids, n_planes: int) -> tuple[np.ndarray, np.ndarray]:
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
    fields,
    origin,
    resolution,
    means,
    transforms,
    coefficients,
    powers,
    planar,
    low,
    high,
    plane_start,
    plane_clusters,
):  # pragma: no cover - compiled
    n_fields = fields.shape[0]
    for i in numba.prange(fields.shape[1]):
        x = origin[0] + (i + 0.5) * resolution
        row_values = np.empty(fields.shape[3])
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
                if k_high < k_low:
                    continue
                # The row's kernel codes, then their values in one loop LLVM vectorises, then
                # the sums: twice as fast as voxel by voxel, the same to the last bit.
                run = row_values[: k_high - k_low + 1]
                for k in range(k_low, k_high + 1):
                    dz = origin[2] + (k + 0.5) * resolution - means[m, 2]
                    p0 = a0 + t[0, 2] * dz
                    p1 = a1 + t[1, 2] * dz
                    p2 = a2 + t[2, 2] * dz
                    r2 = p0 * p0 + p1 * p1 + p2 * p2
                    r_max = max(abs(p0), abs(p1), abs(p2))
                    run[k - k_low] = kernel_code(r2, r_max, planar[m])
                kernels_of_codes_serial(run)
                for f in range(n_fields):
                    coefficient = coefficients[m, f]
                    if powers[f] == 2:
                        for k in range(k_low, k_high + 1):
                            fields[f, i, j, k] += coefficient * (run[k - k_low] * run[k - k_low])
                    else:
                        for k in range(k_low, k_high + 1):
                            fields[f, i, j, k] += coefficient * run[k - k_low]


def accumulate_local_grids_reference(
    fields: np.ndarray, lattice: Lattice, local: LocalGrids
) -> None:
    """Plain NumPy twin of `accumulate_local_grids`, one local grid at a time."""
    origin, resolution = lattice.origin, lattice.resolution
    powers = FIELD_POWERS[: len(fields)]
    for m in range(len(local)):
        low, high = local.low[m], local.high[m]
        if np.any(high < low):
            continue
        axes = [origin[a] + (np.arange(low[a], high[a] + 1) + 0.5) * resolution for a in range(3)]
        points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1) - local.means[m]
        values = cluster_kernel_reference(points @ local.transforms[m].T, local.planar[m])
        box = tuple(slice(low[a], high[a] + 1) for a in range(3))
        for f, power in enumerate(powers):
            fields[(f, *box)] += local.coefficients[m, f] * values**power
