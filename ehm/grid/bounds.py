"""Where a grid lies: checked bounds and voxel counts, and the box a map's kernels cover."""

from __future__ import annotations

import numba
import numpy as np

from ehm.core.snapshot import MapSnapshot
from ehm.errors import EmptyMapError, InputError


def bytes_per_voxel(with_std: bool = False) -> int:
    """Bytes a grid holds per voxel: float64 scores and probabilities, and with the std two
    float64 sums and the std itself."""
    return 40 if with_std else 16


# Grids that would take more than this are refused before anything is allocated.
DEFAULT_MAX_BYTES = 2**30


def grid_shape(
    bounds: np.ndarray,
    resolution: float,
    dim: int,
    max_bytes: int = DEFAULT_MAX_BYTES,
    voxel_bytes: int = bytes_per_voxel(),
) -> tuple[np.ndarray, tuple[int, ...]]:
    """Check grid bounds (2, dim) [low corner, high corner], metres, and a resolution, metres;
    return the float64 low corner and the voxels per axis. InputError for a resolution <= 0,
    bounds of the wrong shape, not finite, inverted or empty, and for grids that would take more
    than `max_bytes` (`voxel_bytes` per voxel), before anything is allocated."""
    resolution = float(resolution)
    if not np.isfinite(resolution) or resolution <= 0.0:
        raise InputError(f"grid resolution must be a positive number of metres, got {resolution}")
    expected = f"grid bounds must have shape (2, {dim}), [low corner, high corner]"
    try:
        bounds = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise InputError(f"{expected}, got {bounds!r}") from error
    if bounds.shape != (2, dim):
        raise InputError(f"{expected}, got shape {bounds.shape}")
    if not np.all(np.isfinite(bounds)):
        raise InputError(f"grid bounds must be finite, got {bounds.tolist()}")
    low, high = bounds
    if np.any(high < low):
        raise InputError(
            f"grid bounds are inverted: high corner {high.tolist()} lies below low corner "
            f"{low.tolist()} on axis {int(np.argmax(high < low))}"
        )
    if np.any(high == low):
        axis = int(np.argmax(high == low))
        raise InputError(f"grid bounds are empty: zero extent on axis {axis}")
    counts = np.maximum(np.ceil((high - low) / resolution - 1e-9), 1.0)
    n_bytes = float(np.prod(counts)) * voxel_bytes
    if n_bytes > max_bytes:
        shape = " x ".join(f"{c:.0f}" for c in counts)
        raise InputError(
            f"a grid of {shape} voxels at {resolution} m would take {n_bytes / 2**30:.2f} GiB, "
            f"more than the limit of {max_bytes / 2**30:.2f} GiB: coarsen the resolution, "
            "shrink the bounds or raise the limit (max_bytes; --max-gib)"
        )
    return low.copy(), tuple(int(c) for c in counts)


def aligned_bounds(bounds: np.ndarray, resolution: float) -> np.ndarray:
    """(2, d) `bounds`, metres, widened outward to multiples of `resolution`, metres, so
    that the grid's voxels are OctoMap's voxels (ehm.io.exports)."""
    box = np.asarray(bounds, dtype=np.float64)
    low = np.floor(box[0] / resolution - 1e-9) * resolution
    high = np.ceil(box[1] / resolution + 1e-9) * resolution
    return np.stack([low, high])


def support_bounds(snapshot: MapSnapshot) -> np.ndarray:
    """(2, d) metres: the smallest box holding every kernel's support (all of the map where
    any kernel is non-zero). EmptyMapError for a map without clusters: it has no extent."""
    if len(snapshot.means) == 0:
        raise EmptyMapError(
            "the map has no clusters (no scan gave enough samples together), so it covers "
            "nothing: every point reads 0.5; give bounds for a grid of it anyway"
        )
    half = support_half_widths(snapshot.transforms, snapshot.planar_kernel)
    means = snapshot.means
    return np.stack([(means - half).min(axis=0), (means + half).max(axis=0)])


def support_half_widths(transforms: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """(M, d) metres: half-widths of the axis-aligned box around each kernel's support, for
    kernel transforms (M, d, d) 1/m (d 2 or 3, as maps are) and planar (M,) bool.

    The support {mu + T^-1 u} with |u| < 1 (ball) reaches |row a of T^-1| along world axis a;
    with max_b |u_b| < 1 (box, where `planar`) it reaches the sum of |row a of T^-1|. Each
    T^-1 is the adjugate over the determinant, in one compiled pass on both cores (faster than
    batched np.linalg.inv)."""
    transforms = np.ascontiguousarray(transforms, dtype=np.float64)
    return _half_widths(transforms, np.ascontiguousarray(planar, dtype=np.bool_))


@numba.njit(cache=True, parallel=True)
def _half_widths(transforms, planar):  # pragma: no cover - compiled
    """support_half_widths of (M, d, d) transforms, d 2 or 3."""
    m_count, d = transforms.shape[0], transforms.shape[1]
    half = np.empty((m_count, d))
    for m in numba.prange(m_count):
        t = transforms[m]
        inverse = np.empty((d, d))
        if d == 2:
            det = t[0, 0] * t[1, 1] - t[0, 1] * t[1, 0]
            inverse[0, 0], inverse[0, 1] = t[1, 1] / det, -t[0, 1] / det
            inverse[1, 0], inverse[1, 1] = -t[1, 0] / det, t[0, 0] / det
        else:
            for r in range(3):
                for c in range(3):
                    # Cofactor of t[c, r]: the adjugate is the cofactors' transpose.
                    r1, r2 = (c + 1) % 3, (c + 2) % 3
                    c1, c2 = (r + 1) % 3, (r + 2) % 3
                    inverse[r, c] = t[r1, c1] * t[r2, c2] - t[r1, c2] * t[r2, c1]
            det = t[0, 0] * inverse[0, 0] + t[0, 1] * inverse[1, 0] + t[0, 2] * inverse[2, 0]
            for r in range(3):
                for c in range(3):
                    inverse[r, c] /= det
        for a in range(d):
            total = 0.0
            for b in range(d):
                total += abs(inverse[a, b]) if planar[m] else inverse[a, b] * inverse[a, b]
            half[m, a] = total if planar[m] else np.sqrt(total)
    return half


def support_half_widths_reference(transforms: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """Plain NumPy twin of `support_half_widths`."""
    inverse = np.linalg.inv(transforms)
    return np.where(planar[:, None], np.abs(inverse).sum(axis=2), np.linalg.norm(inverse, axis=2))
