"""The nearest site of every voxel of a 3D grid: an exact Euclidean feature transform between
voxel centres, what scipy.ndimage.distance_transform_edt(..., return_indices=True) gives,
computed axis by axis on both cores.

Felzenszwalb & Huttenlocher (2012): the squared distance to the nearest site is separable. Along
each line of the last axis, every voxel finds its nearest site on that line; along each line of
the middle axis, the lower envelope of the parabolas (j - j')^2 + f(j') over those distances
gives the nearest site in each plane; along the first axis the same over the planes' gives the
nearest in the grid. Each pass treats its lines independently, so they run on as many threads
as there are. Squared distances are integers (voxel units), so the result is exact; where two
sites are equally near, either may be given. Distances and sites are held in 32 bits (a grid of
up to 2^31 voxels), which halves the memory each pass streams through.
"""

from __future__ import annotations

import numba
import numpy as np

# The squared distance of a voxel with no site on its line (plane, grid).
NO_SITE = np.iinfo(np.int32).max


def nearest_sites(
    sites: np.ndarray, offset: np.ndarray | None = None, grid_shape: np.ndarray | None = None
) -> np.ndarray:
    """(X, Y, Z) int32: for each voxel of the (X, Y, Z) bool box `sites`, the flat (C order)
    index of the nearest voxel that is a site, -1 where the box holds none; flat in the grid
    of `grid_shape` (3,) that holds the box with its low corner at voxel `offset` (3,)
    (default: the box itself)."""
    sites = np.ascontiguousarray(sites, dtype=np.bool_)
    if sites.ndim != 3:
        raise ValueError(f"nearest_sites needs a 3D grid, got {sites.ndim}D")
    offset = np.zeros(3, dtype=np.int64) if offset is None else np.asarray(offset, np.int64)
    grid_shape = np.array(sites.shape) if grid_shape is None else np.asarray(grid_shape)
    if np.prod(grid_shape.astype(np.float64)) >= 2.0**31:
        raise ValueError(f"nearest_sites needs fewer than 2^31 voxels, got {tuple(grid_shape)}")
    if not sites.any():
        return np.full(sites.shape, -1, dtype=np.int32)
    return _nearest_sites(sites, offset, grid_shape.astype(np.int64))


@numba.njit(cache=True, parallel=True)
def _nearest_sites(sites, offset, grid_shape):  # pragma: no cover - compiled
    """See nearest_sites (a box with at least one site)."""
    nx, ny, nz = sites.shape
    squared = np.empty(sites.shape, dtype=np.int32)
    found = np.empty(sites.shape, dtype=np.int32)
    # Along the last axis: the nearest site on each line, by a sweep each way.
    for i in numba.prange(nx):
        for j in range(ny):
            last = -1
            for k in range(nz):
                if sites[i, j, k]:
                    last = k
                found[i, j, k] = last
            # The flat index, in the grid, of the line's first voxel.
            line = ((i + offset[0]) * grid_shape[1] + j + offset[1]) * grid_shape[2] + offset[2]
            following = -1
            for k in range(nz - 1, -1, -1):
                if sites[i, j, k]:
                    following = k
                before = found[i, j, k]
                best = before
                if following >= 0 and (before < 0 or following - k < k - before):
                    best = following
                found[i, j, k] = -1 if best < 0 else line + best
                squared[i, j, k] = NO_SITE if best < 0 else (k - best) * (k - best)
    # Along the middle axis, then the first: lower envelopes over the lines' squared distances.
    for i in numba.prange(nx):
        scratch = _line_scratch(ny)
        for k in range(nz):
            _envelope(squared[i, :, k], found[i, :, k], scratch)
    for j in numba.prange(ny):
        scratch = _line_scratch(nx)
        for k in range(nz):
            _envelope(squared[:, j, k], found[:, j, k], scratch)
    return found


@numba.njit(cache=True)
def _line_scratch(n):  # pragma: no cover - compiled
    """Room for one line of `n` voxels: (the parabolas of the envelope (n,) int64, where each
    begins (n + 1,) float64, the line's squared distances and sites (n,) int32 each)."""
    return (
        np.empty(n, dtype=np.int64),
        np.empty(n + 1),
        np.empty(n, dtype=np.int32),
        np.empty(n, dtype=np.int32),
    )


@numba.njit(cache=True, inline="always")
def _envelope(squared, found, scratch):  # pragma: no cover - compiled
    """One line: squared (n,) int32, each voxel's squared distance to its nearest site in the
    lower dimensions (NO_SITE: none), and found (n,) int32 that site; both replaced in place
    by the nearest over the whole line, (q - q')^2 + squared[q'] at the best q'."""
    parabolas, starts, f, site = scratch
    n = len(squared)
    for q in range(n):
        f[q] = squared[q]
        site[q] = found[q]
    top = -1
    for q in range(n):
        if f[q] == NO_SITE:
            continue
        s = -np.inf
        while top >= 0:
            p = parabolas[top]
            # Where the parabola of q comes below that of p.
            s = ((f[q] + q * q) - (f[p] + p * p)) / (2.0 * (q - p))
            if s <= starts[top]:
                top -= 1
            else:
                break
        top += 1
        parabolas[top] = q
        starts[top] = s
        starts[top + 1] = np.inf
    if top < 0:
        return
    at = 0
    for q in range(n):
        while starts[at + 1] < q:
            at += 1
        p = parabolas[at]
        squared[q] = (q - p) * (q - p) + f[p]
        found[q] = site[p]


def nearest_sites_reference(
    sites: np.ndarray, offset: np.ndarray | None = None, grid_shape: np.ndarray | None = None
) -> np.ndarray:
    """scipy's feature transform in the form of `nearest_sites`."""
    from scipy import ndimage

    sites = np.asarray(sites, dtype=bool)
    if not sites.any():
        return np.full(sites.shape, -1, dtype=np.int32)
    offset = np.zeros(3, dtype=np.int64) if offset is None else np.asarray(offset)
    grid_shape = sites.shape if grid_shape is None else tuple(grid_shape)
    index = ndimage.distance_transform_edt(~sites, return_distances=False, return_indices=True)
    placed = tuple(index[axis] + offset[axis] for axis in range(3))
    return np.ravel_multi_index(placed, grid_shape).astype(np.int32)
