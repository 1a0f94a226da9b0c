"""A spatial hash of kernel supports: at any point, every kernel that is not zero there, found
exactly and without a nearest-neighbour search.

Both kernels vanish outside a bounded support: the ellipsoid |T_m (x - mu_m)| < 1 of k_SP and
the box max_a |T_m (x - mu_m)|_a < 1 of the planar kernel (ehm.core.model.kernels). The hash lists
each kernel in every cell that the bounding box of its support overlaps; the kernels of a point
are among those its cell lists, and evaluating them keeps exactly the ones that are not zero.
So a point's features are all its kernels, the sum the grids take (Sec. 3.5), and training,
point queries and grids share one model.

Fine kernels (surfaces) reach a few decimetres, coarse ones (open space along rays) a metre or
two, so each scale has cells of its own side, a few times its cluster radius: a kernel sits in
a few cells and a cell lists a few dozen kernels. One table holds both scales; a cell's key
packs its integer coordinates (20 bits per axis in 3D, 31 in 2D, from -2^19 and -2^30) and the
scale.

The table is updated in place, in time proportional to the kernels that change: each cell owns
a block of a shared pool of kernel rows, sorted, with room to spare; a kernel is removed from
its cells' blocks and inserted into them in order, and a full block moves to the end of the
pool with twice the room. The pool is compacted when half of it is abandoned blocks and
the table doubles when half of its slots are taken, so growth costs amortized O(1) per entry.
"""

from __future__ import annotations

import numba
import numpy as np

from ehm.core.model.features import SparseFeatures, add_to_sums, kernel_at
from ehm.core.model.kernels import cluster_kernel_reference
from ehm.core.search.hashing import EMPTY_KEY, hash_slot
from ehm.errors import InputError

# Cell side of each scale, as a multiple of its cluster radius (MapConfig.cluster_radius,
# free_cluster_radius). Smaller cells list fewer kernels a point does not touch but list each
# kernel in more cells: on the sample scan's map, 60 kernels looked at per point for 8.3 that
# are not zero, in 2.4 MB; 33 in 7.4 MB with cells half as large.
CELL_FACTORS = (4.0, 2.0)
_MIN_BLOCK = 4


def axis_bits(dim: int) -> int:
    """Bits of each axis in a cell key: the key has dim of them and one for the scale."""
    return (63 - 1) // dim


@numba.njit(cache=True, inline="always")
def _pack(cell, bits, coarse):  # pragma: no cover - compiled
    key = np.int64(0)
    half = np.int64(1) << (bits - 1)
    for a in range(cell.shape[0]):
        key = (key << bits) | (np.int64(cell[a]) + half)
    return (key << 1) | np.int64(coarse)


@numba.njit(cache=True, inline="always")
def _cell_of(points, i, side, bits, coarse):  # pragma: no cover - compiled
    """Key of the cell of side `side` and scale `coarse` that holds point i (coordinates
    beyond the keys' range clamped to it)."""
    half = np.int64(1) << (bits - 1)
    limit = float(half - 1)
    key = np.int64(0)
    for a in range(points.shape[1]):
        c = np.int64(min(max(np.floor(points[i, a] / side), -limit), limit))
        key = (key << bits) | (c + half)
    return (key << 1) | np.int64(coarse)


@numba.njit(cache=True, inline="always")
def _cell_key(m, c, lo, hi, bits, coarse, cell):  # pragma: no cover - compiled
    """Key of cell c (0 .. cells - 1) of the box of cells lo[m] .. hi[m] (inclusive)."""
    for a in range(lo.shape[1]):
        extent = hi[m, a] - lo[m, a] + 1
        cell[a] = lo[m, a] + c % extent
        c //= extent
    return _pack(cell, bits, coarse[m])


@numba.njit(cache=True, inline="always")
def _n_cells(m, lo, hi):  # pragma: no cover - compiled
    n = 1
    for a in range(lo.shape[1]):
        n *= hi[m, a] - lo[m, a] + 1
    return n


@numba.njit(cache=True)
def _insert(
    table_keys, starts, counts, capacities, pool, used, kernels, lo, hi, coarse, bits
):  # pragma: no cover - compiled
    """List `kernels` in every cell from lo[m] to hi[m] (inclusive, per axis) of scale
    coarse[m]. used: [pool entries in use up to the end, table slots taken]. Stops before a
    kernel that would leave the table more than half full or overrun the pool, and returns how
    many kernels it listed."""
    cell = np.empty(lo.shape[1], dtype=np.int64)
    for done in range(len(kernels)):
        m = kernels[done]
        n_cells = _n_cells(m, lo, hi)
        need = 0
        new_cells = 0
        for c in range(n_cells):
            s = hash_slot(table_keys, _cell_key(m, c, lo, hi, bits, coarse, cell))
            if table_keys[s] == EMPTY_KEY:
                need += _MIN_BLOCK
                new_cells += 1
            elif counts[s] == capacities[s]:
                need += 2 * capacities[s]
        if used[0] + need > len(pool) or 2 * (used[1] + new_cells) > len(table_keys):
            return done
        for c in range(n_cells):
            key = _cell_key(m, c, lo, hi, bits, coarse, cell)
            s = hash_slot(table_keys, key)
            if table_keys[s] == EMPTY_KEY:
                table_keys[s] = key
                starts[s] = used[0]
                counts[s] = 0
                capacities[s] = _MIN_BLOCK
                used[0] += _MIN_BLOCK
                used[1] += 1
            elif counts[s] == capacities[s]:
                grown = 2 * capacities[s]
                pool[used[0] : used[0] + counts[s]] = pool[starts[s] : starts[s] + counts[s]]
                starts[s] = used[0]
                capacities[s] = grown
                used[0] += grown
            # Blocks stay sorted by kernel row, so a point's kernels come in an order that does
            # not depend on the order they were listed in (sums are the same to the last bit
            # in a map rebuilt from its saved state).
            j = starts[s] + counts[s]
            while j > starts[s] and pool[j - 1] > m:
                pool[j] = pool[j - 1]
                j -= 1
            pool[j] = m
            counts[s] += 1
    return len(kernels)


@numba.njit(cache=True)
def _remove(
    table_keys, starts, counts, pool, kernels, lo, hi, coarse, bits
):  # pragma: no cover - compiled
    """Take `kernels` out of the cells they were listed in (lo, hi, coarse as when listed)."""
    cell = np.empty(lo.shape[1], dtype=np.int64)
    for m in kernels:
        for c in range(_n_cells(m, lo, hi)):
            s = hash_slot(table_keys, _cell_key(m, c, lo, hi, bits, coarse, cell))
            end = starts[s] + counts[s]
            for j in range(starts[s], end):
                if pool[j] == m:
                    for k in range(j, end - 1):
                        pool[k] = pool[k + 1]
                    counts[s] -= 1
                    break


@numba.njit(cache=True)
def _place_cells(
    keys, sizes, table_keys, counts, pending, lo, hi, coarse, bits
):  # pragma: no cover - compiled
    """Put in the empty table `keys` every cell of the old table that lists kernels and every
    cell of `pending` kernels; sizes (len(keys),) int64 gains the entries each slot will hold.
    Returns the slots taken."""
    taken = 0
    for s in range(len(table_keys)):
        if table_keys[s] != EMPTY_KEY and counts[s] > 0:
            t = hash_slot(keys, table_keys[s])
            keys[t] = table_keys[s]
            sizes[t] = counts[s]
            taken += 1
    cell = np.empty(lo.shape[1], dtype=np.int64)
    for m in pending:
        for c in range(_n_cells(m, lo, hi)):
            key = _cell_key(m, c, lo, hi, bits, coarse, cell)
            t = hash_slot(keys, key)
            if keys[t] == EMPTY_KEY:
                keys[t] = key
                taken += 1
            sizes[t] += 1
    return taken


@numba.njit(cache=True)
def _rebuild(
    table_keys, counts, starts, pool, new_size, pending, lo, hi, coarse, bits
):  # pragma: no cover - compiled
    """A table and a compact pool holding every entry of the old ones, with room in each
    cell's block for the entries of `pending` kernels (still to be listed) and a quarter more:
    (keys, starts, counts, capacities, pool, pool entries in use, slots taken). new_size:
    slots enough for every old cell and every pending entry."""
    # Distinct cells first, in a table large enough for every entry: the new table holds four
    # times as many slots as there are cells, so it can take as many again before a rebuild.
    scratch = np.full(new_size, EMPTY_KEY, dtype=np.int64)
    distinct = _place_cells(
        scratch,
        np.zeros(new_size, dtype=np.int64),
        table_keys,
        counts,
        pending,
        lo,
        hi,
        coarse,
        bits,
    )
    new_size = 64
    while new_size < 4 * distinct:
        new_size *= 2
    keys = np.full(new_size, EMPTY_KEY, dtype=np.int64)
    new_starts = np.zeros(new_size, dtype=np.int64)
    new_counts = np.zeros(new_size, dtype=np.int64)
    capacities = np.zeros(new_size, dtype=np.int64)
    taken = _place_cells(keys, capacities, table_keys, counts, pending, lo, hi, coarse, bits)
    end = 0
    for t in range(new_size):
        if keys[t] != EMPTY_KEY:
            capacities[t] = max(_MIN_BLOCK, capacities[t] + capacities[t] // 4)
            new_starts[t] = end
            end += capacities[t]
    new_pool = np.empty(end + end // 4, dtype=np.int32)
    for s in range(len(table_keys)):
        if table_keys[s] != EMPTY_KEY and counts[s] > 0:
            t = hash_slot(keys, table_keys[s])
            new_pool[new_starts[t] : new_starts[t] + counts[s]] = pool[
                starts[s] : starts[s] + counts[s]
            ]
            new_counts[t] = counts[s]
    return keys, new_starts, new_counts, capacities, new_pool, end, taken


@numba.njit(cache=True, inline="always")
def _block(points, i, scale, table_keys, starts, counts, sides, bits):  # pragma: no cover
    """(first, last + 1) positions in the pool of the kernels listed in point i's cell of
    `scale` (0 fine, 1 coarse); empty where the cell lists none."""
    s = hash_slot(table_keys, _cell_of(points, i, sides[scale], bits, scale))
    if table_keys[s] == EMPTY_KEY:
        return 0, 0
    return starts[s], starts[s] + counts[s]


@numba.njit(cache=True, parallel=True)
def _candidate_counts(
    points, table_keys, starts, counts, sides, bits
):  # pragma: no cover - compiled
    """(n,) int64 kernels listed in the cells (both scales) of each point: a bound on its
    features."""
    n = points.shape[0]
    found = np.zeros(n, dtype=np.int64)
    for i in numba.prange(n):
        for scale in range(2):
            first, end = _block(points, i, scale, table_keys, starts, counts, sides, bits)
            found[i] += end - first
    return found


@numba.njit(cache=True, parallel=True)
def _fill_features(
    points, bound, table_keys, starts, counts, pool, sides, bits, means, transforms, planar
):  # pragma: no cover - compiled
    """Kernel rows and values at each point, written from bound[i] on; returns (rows, values,
    nnz (n,) int64 per point)."""
    n = points.shape[0]
    rows = np.empty(bound[n], dtype=np.int64)
    values = np.empty(bound[n])
    nnz = np.zeros(n, dtype=np.int64)
    for i in numba.prange(n):
        out = bound[i]
        for scale in range(2):
            first, end = _block(points, i, scale, table_keys, starts, counts, sides, bits)
            for j in range(first, end):
                m = pool[j]
                value = kernel_at(points, i, m, means, transforms, planar)
                if value != 0.0:
                    rows[out] = m
                    values[out] = value
                    out += 1
        nnz[i] = out - bound[i]
    return rows, values, nnz


@numba.njit(cache=True, parallel=True)
def _compact(bound, indptr, rows, values):  # pragma: no cover - compiled
    """Rows and values written from bound[i] on, packed to start at indptr[i]."""
    n = len(indptr) - 1
    packed_rows = np.empty(indptr[n], dtype=np.int64)
    packed_values = np.empty(indptr[n])
    for i in numba.prange(n):
        size = indptr[i + 1] - indptr[i]
        packed_rows[indptr[i] : indptr[i + 1]] = rows[bound[i] : bound[i] + size]
        packed_values[indptr[i] : indptr[i + 1]] = values[bound[i] : bound[i] + size]
    return packed_rows, packed_values


@numba.njit(cache=True, parallel=True)
def support_decision_values(
    points,
    table_keys,
    starts,
    counts,
    pool,
    sides,
    bits,
    means,
    transforms,
    planar,
    weights,
    bias,
    inverse_precision,
    with_variance,
):  # pragma: no cover - compiled
    """(n,) float64 bias + sum_m w_m phi_m(x) over every kernel at each point, and, when
    with_variance, (n, 2) [sum_m phi_m^2 / lambda_m, sum_m phi_m] (else (0, 2))."""
    n = points.shape[0]
    scores = np.full(n, bias)
    variance_sums = np.zeros((n if with_variance else 0, 2))
    for i in numba.prange(n):
        for scale in range(2):
            first, end = _block(points, i, scale, table_keys, starts, counts, sides, bits)
            for j in range(first, end):
                m = pool[j]
                value = kernel_at(points, i, m, means, transforms, planar)
                if value != 0.0:
                    add_to_sums(
                        scores,
                        variance_sums,
                        i,
                        m,
                        value,
                        weights,
                        inverse_precision,
                        with_variance,
                    )
    return scores, variance_sums


def support_boxes(
    means: np.ndarray, transforms: np.ndarray, planar: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(M, d) lower and upper corners, metres, of the box around each kernel's support.

    The support is u = T (x - mu) in the unit ball (or the unit box where planar), so x - mu =
    T^-1 u; along axis i it reaches |row i of T^-1| (the ball) or the sum of its absolute
    values (the box)."""
    if len(means) == 0:
        return means.copy(), means.copy()
    inverse = np.linalg.inv(transforms)
    half = np.where(planar[:, None], np.abs(inverse).sum(axis=2), np.linalg.norm(inverse, axis=2))
    return means - half, means + half


class SupportHash:
    """Every kernel of a map listed in the cells of a hash its support overlaps (see module
    docstring). dim: 2 or 3; sides: (fine, coarse) cell sides, metres."""

    def __init__(self, dim: int, sides: tuple[float, float]) -> None:
        self.dim = dim
        self.sides = np.array(sides, dtype=np.float64)
        self.bits = axis_bits(dim)
        self._used = np.zeros(2, dtype=np.int64)  # pool entries to the end, table slots taken
        self._table = self._empty_table(64)
        self._pool = np.zeros(256, dtype=np.int32)
        self._lo = np.zeros((0, dim), dtype=np.int32)
        self._hi = np.zeros((0, dim), dtype=np.int32)
        self._coarse = np.zeros(0, dtype=np.int64)
        self._listed = np.zeros(0, dtype=bool)

    @classmethod
    def of_radii(cls, dim: int, cluster_radius: float, free_cluster_radius: float) -> SupportHash:
        """An empty hash with cells CELL_FACTORS times each scale's cluster radius."""
        fine, coarse = CELL_FACTORS
        return cls(dim, (fine * cluster_radius, coarse * free_cluster_radius))

    @staticmethod
    def _empty_table(size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        keys = np.full(size, EMPTY_KEY, dtype=np.int64)
        return (
            keys,
            np.zeros(size, dtype=np.int64),
            np.zeros(size, dtype=np.int64),
            np.zeros(size, dtype=np.int64),
        )

    @property
    def nbytes(self) -> int:
        arrays = [*self._table, self._pool, self._lo, self._hi, self._coarse, self._listed]
        return int(sum(a.nbytes for a in arrays))

    # -------------------------------------------------------------- updates
    def update(
        self,
        rows: np.ndarray,
        means: np.ndarray,
        transforms: np.ndarray,
        planar: np.ndarray,
        coarse: np.ndarray,
    ) -> None:
        """List kernels `rows` ((R,) int64) anew after they were added or changed: means (M, d)
        metres, transforms (M, d, d) 1/m, planar (M,) bool kernel, coarse (M,) bool scale, for
        every kernel of the map (M at least as many as ever listed)."""
        self._grow_kernels(len(means))
        rows = np.unique(np.asarray(rows, dtype=np.int64))
        listed = rows[self._listed[rows]]
        keys, starts, counts, _ = self._table
        _remove(
            keys, starts, counts, self._pool, listed, self._lo, self._hi, self._coarse, self.bits
        )
        low, high = support_boxes(means[rows], transforms[rows], planar[rows])
        side = self.sides[coarse[rows].astype(np.int64)][:, None]
        lo, hi = np.floor(low / side), np.floor(high / side)
        limit = 2.0 ** (self.bits - 1)
        if len(rows) and not (lo.min() >= -limit and hi.max() < limit):
            raise InputError(
                f"a kernel reaches more than {limit * self.sides[0]:.0f} m from the world "
                "origin, beyond the cells of the support hash"
            )
        self._lo[rows], self._hi[rows] = lo, hi
        self._coarse[rows] = coarse[rows]
        self._listed[rows] = True
        pending = rows
        while len(pending):
            done = _insert(
                *self._table,
                self._pool,
                self._used,
                pending,
                self._lo,
                self._hi,
                self._coarse,
                self.bits,
            )
            pending = pending[done:]
            if len(pending):
                self._make_room(pending)

    def _grow_kernels(self, n: int) -> None:
        old = len(self._listed)
        if n <= old:
            return
        size = max(n, 2 * old, 64)
        for name in ("_lo", "_hi", "_coarse", "_listed"):
            array = getattr(self, name)
            grown = np.zeros((size, *array.shape[1:]), dtype=array.dtype)
            grown[:old] = array
            setattr(self, name, grown)

    def _make_room(self, pending: np.ndarray) -> None:
        """Rebuild the table (at most half full once `pending` kernels are listed) and a
        compact pool whose blocks have room for the pending kernels' entries."""
        cells = int(np.prod(self._hi[pending] - self._lo[pending] + 1, axis=1).sum())
        keys, starts, counts, _ = self._table
        size = len(keys)
        while 2 * (self._used[1] + cells) > size:
            size *= 2
        *table, pool, end, taken = _rebuild(
            keys,
            counts,
            starts,
            self._pool,
            size,
            pending,
            self._lo,
            self._hi,
            self._coarse,
            self.bits,
        )
        self._table, self._pool = tuple(table), pool
        self._used[:] = end, taken

    # -------------------------------------------------------------- queries
    def _arguments(self) -> tuple:
        keys, starts, counts, _ = self._table
        return keys, starts, counts, self._pool, self.sides, self.bits

    def features(
        self, points: np.ndarray, means: np.ndarray, transforms: np.ndarray, planar: np.ndarray
    ) -> SparseFeatures:
        """Every kernel not zero at each of (n, d) points, metres, as the points' features."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        keys, starts, counts, pool, sides, bits = self._arguments()
        bound = np.zeros(len(points) + 1, dtype=np.int64)
        np.cumsum(_candidate_counts(points, keys, starts, counts, sides, bits), out=bound[1:])
        rows, values, nnz = _fill_features(
            points, bound, keys, starts, counts, pool, sides, bits, means, transforms, planar
        )
        indptr = np.zeros(len(points) + 1, dtype=np.int64)
        np.cumsum(nnz, out=indptr[1:])
        packed_rows, packed_values = _compact(bound, indptr, rows, values)
        return SparseFeatures(indptr, packed_rows, packed_values)

    def decision_values(
        self,
        points: np.ndarray,
        means: np.ndarray,
        transforms: np.ndarray,
        planar: np.ndarray,
        weights: np.ndarray,
        bias: float,
        inverse_precision: np.ndarray,
        with_variance: bool,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) log-odds bias + w^T phi(x) over every kernel at each of (n, d) points, and
        with_variance, their (n, 2) variance sums (see support_decision_values)."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        return support_decision_values(
            points,
            *self._arguments(),
            means,
            transforms,
            planar,
            weights,
            float(bias),
            inverse_precision,
            with_variance,
        )


def support_features_reference(
    points: np.ndarray, means: np.ndarray, transforms: np.ndarray, planar: np.ndarray
) -> SparseFeatures:
    """Plain NumPy twin of `SupportHash.features`: every kernel evaluated at every point
    (rows in increasing order per point)."""
    offsets = points[:, None, :] - means[None, :, :]
    projected = np.einsum("mab,nmb->nma", transforms, offsets)
    values = cluster_kernel_reference(projected, np.broadcast_to(planar, projected.shape[:2]))
    point, rows = np.nonzero(values)
    indptr = np.zeros(len(points) + 1, dtype=np.int64)
    np.cumsum(np.bincount(point, minlength=len(points)), out=indptr[1:])
    return SparseFeatures(indptr, rows.astype(np.int64), values[point, rows])
