"""Where a grid lies: checked bounds and voxel counts, and the box a map's kernels cover."""

from __future__ import annotations

import numpy as np

from ehm.core.model.kernels import support_half_widths
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
