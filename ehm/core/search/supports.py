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

A cell's block is long where surfaces crowd (146 kernels listed for 11 not zero at a point
of a TUM sequence's map), so each entry also holds a mask of the sub-cells of its cell that
the kernel's box overlaps (64 in all): a point evaluates only the kernels whose mask holds its
own sub-cell (42 of the 146 there). Points whose sub-cells match at both scales form a group
(a TUM frame's 139,000 training samples fall into 6,800 such groups), and the groups are
taken cell by cell, so that the next group finds most of its kernels still in cache. Learning
lists each scale's candidates of a sub-cell once, for every group in it; a query, which reads
a point's candidates once, sifts its cells' blocks as it goes.

The table is updated in place, in time proportional to the kernels that change: each cell owns
a block of a shared pool of kernel rows, sorted, with room to spare; a kernel is removed from
its cells' blocks and inserted into them in order, and a full block moves to the end of the
pool with twice the room. The pool is compacted when half of it is abandoned blocks and
the table doubles when half of its slots are taken, so growth costs amortized O(1) per entry.
"""

from __future__ import annotations

import itertools

import numba
import numpy as np

from ehm.core.model.features import SparseFeatures, add_to_sums
from ehm.core.model.kernels import (
    OUTSIDE,
    cluster_kernel_reference,
    kernel_code,
    kernels_of_codes,
    kernels_of_codes_serial,
    projected_radii,
    support_half_widths,
)
from ehm.core.primitives.hashing import (
    EMPTY_KEY,
    first_come_ranks,
    hash_slot,
    rows_by_rank,
    sorted_distinct,
)
from ehm.core.primitives.radix import radix_order
from ehm.errors import InputError

# Cell side of each scale, as a multiple of its cluster radius (MapConfig.cluster_radius,
# free_cluster_radius). Smaller cells list fewer kernels a point does not touch but list each
# kernel in more cells: on the sample scan's map, 60 kernels looked at per point for 8.3 that
# are not zero, in 2.4 MB; 33 in 7.4 MB with cells half as large.
CELL_FACTORS = (4.0, 2.0)
_MIN_BLOCK = 4
# Sub-cells of each cell: 2^SUBCELL_BITS in all (64: 4 per axis in 3D, 8 in 2D), one bit each of
# a uint64 mask.
SUBCELL_BITS = 6


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
def _cell_of(points, i, sub_side, divisions, bits, coarse):  # pragma: no cover - compiled
    """Key of the cell of scale `coarse` that holds point i, its sides `divisions` sub-cells
    of `sub_side` (coordinates beyond the keys' range clamped to it), and the index of the
    point's sub-cell (its bit in the masks of the cell's entries)."""
    half = np.int64(1) << (bits - 1)
    limit = float(half - 1)
    key = np.int64(0)
    index = np.int64(0)
    stride = np.int64(1)
    for a in range(points.shape[1]):
        sub = np.int64(
            min(max(np.floor(points[i, a] / sub_side), -limit * divisions), limit * divisions)
        )
        c = sub // divisions
        index += stride * (sub - c * divisions)
        stride *= divisions
        key = (key << bits) | (c + half)
    return (key << 1) | np.int64(coarse), index


def sub_cell_slabs(dim: int, divisions: int) -> np.ndarray:
    """(dim, divisions, divisions) uint64: the sub-cells of a cell (bit sum_a divisions^a
    c_a for the sub-cell at c, as _cell_of numbers them) whose coordinate along axis a lies
    in lo .. hi, as bits of slabs[a, lo, hi]. A box of sub-cells is the AND of its axes'
    slabs."""
    bit = np.arange(divisions**dim, dtype=np.uint64)
    coordinates = (bit[:, None] // divisions ** np.arange(dim, dtype=np.uint64)) % divisions
    slabs = np.zeros((dim, divisions, divisions), dtype=np.uint64)
    for a in range(dim):
        # The bits of each single coordinate along the axis, then their running ORs.
        single = [
            np.bitwise_or.reduce(np.uint64(1) << bit[coordinates[:, a] == c])
            for c in range(divisions)
        ]
        for lo in range(divisions):
            slab = np.uint64(0)
            for hi in range(lo, divisions):
                slab |= single[hi]
                slabs[a, lo, hi] = slab
    return slabs


@numba.njit(cache=True, inline="always")
def _sub_cell_mask(m, cell, sub_lo, sub_hi, divisions, slabs):  # pragma: no cover - compiled
    """Mask of the sub-cells of `cell` (integer coordinates) that kernel m's box, sub-cells
    sub_lo[m] .. sub_hi[m] (inclusive), overlaps; slabs: sub_cell_slabs."""
    mask = ~np.uint64(0)
    for a in range(cell.shape[0]):
        low = max(sub_lo[m, a] - cell[a] * divisions, 0)
        high = min(sub_hi[m, a] - cell[a] * divisions, divisions - 1)
        mask &= slabs[a, low, high]
    return mask


@numba.njit(cache=True, inline="always")
def _cell_key(m, c, sub_lo, sub_hi, divisions, bits, coarse, cell):  # pragma: no cover
    """Key of cell c (0 .. cells - 1) of the box of cells that holds kernel m's sub-cells
    sub_lo[m] .. sub_hi[m] (inclusive)."""
    for a in range(sub_lo.shape[1]):
        low = sub_lo[m, a] // divisions
        extent = sub_hi[m, a] // divisions - low + 1
        cell[a] = low + c % extent
        c //= extent
    return _pack(cell, bits, coarse[m])


@numba.njit(cache=True, inline="always")
def _n_cells(m, sub_lo, sub_hi, divisions):  # pragma: no cover - compiled
    """Cells that hold kernel m's sub-cells sub_lo[m] .. sub_hi[m]."""
    n = 1
    for a in range(sub_lo.shape[1]):
        n *= sub_hi[m, a] // divisions - sub_lo[m, a] // divisions + 1
    return n


@numba.njit(cache=True)
def _insert(
    table_keys,
    starts,
    counts,
    capacities,
    pool,
    masks,
    used,
    kernels,
    sub_lo,
    sub_hi,
    divisions,
    coarse,
    bits,
    slabs,
):  # pragma: no cover - compiled
    """List `kernels` in every cell of scale coarse[m] that holds one of the sub-cells
    sub_lo[m] .. sub_hi[m] (inclusive, per axis), each entry with the mask of those sub-cells
    in it (slabs: sub_cell_slabs). used: [pool entries in use up to the end, table slots
    taken]. Stops before a kernel that would leave the table more than half full or overrun
    the pool, and returns how many kernels it listed."""
    cell = np.empty(sub_lo.shape[1], dtype=np.int64)
    for done in range(len(kernels)):
        m = kernels[done]
        n_cells = _n_cells(m, sub_lo, sub_hi, divisions)
        need = 0
        new_cells = 0
        for c in range(n_cells):
            key = _cell_key(m, c, sub_lo, sub_hi, divisions, bits, coarse, cell)
            s = hash_slot(table_keys, key)
            if table_keys[s] == EMPTY_KEY:
                need += _MIN_BLOCK
                new_cells += 1
            elif counts[s] == capacities[s]:
                need += 2 * capacities[s]
        if used[0] + need > len(pool) or 2 * (used[1] + new_cells) > len(table_keys):
            return done
        for c in range(n_cells):
            key = _cell_key(m, c, sub_lo, sub_hi, divisions, bits, coarse, cell)
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
                masks[used[0] : used[0] + counts[s]] = masks[starts[s] : starts[s] + counts[s]]
                starts[s] = used[0]
                capacities[s] = grown
                used[0] += grown
            # Blocks stay sorted by kernel row, so a point's kernels come in an order that does
            # not depend on the order they were listed in (sums are the same to the last bit
            # in a map rebuilt from its saved state).
            j = starts[s] + counts[s]
            while j > starts[s] and pool[j - 1] > m:
                pool[j] = pool[j - 1]
                masks[j] = masks[j - 1]
                j -= 1
            pool[j] = m
            masks[j] = _sub_cell_mask(m, cell, sub_lo, sub_hi, divisions, slabs)
            counts[s] += 1
    return len(kernels)


@numba.njit(cache=True)
def _remove(
    table_keys, starts, counts, pool, masks, kernels, sub_lo, sub_hi, divisions, coarse, bits
):  # pragma: no cover - compiled
    """Take `kernels` out of the cells they were listed in (sub_lo, sub_hi, coarse as when
    listed)."""
    cell = np.empty(sub_lo.shape[1], dtype=np.int64)
    for m in kernels:
        for c in range(_n_cells(m, sub_lo, sub_hi, divisions)):
            key = _cell_key(m, c, sub_lo, sub_hi, divisions, bits, coarse, cell)
            s = hash_slot(table_keys, key)
            end = starts[s] + counts[s]
            for j in range(starts[s], end):
                if pool[j] == m:
                    for k in range(j, end - 1):
                        pool[k] = pool[k + 1]
                        masks[k] = masks[k + 1]
                    counts[s] -= 1
                    break


@numba.njit(cache=True)
def _place_cells(
    keys, sizes, table_keys, counts, pending, sub_lo, sub_hi, divisions, coarse, bits
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
    cell = np.empty(sub_lo.shape[1], dtype=np.int64)
    for m in pending:
        for c in range(_n_cells(m, sub_lo, sub_hi, divisions)):
            key = _cell_key(m, c, sub_lo, sub_hi, divisions, bits, coarse, cell)
            t = hash_slot(keys, key)
            if keys[t] == EMPTY_KEY:
                keys[t] = key
                taken += 1
            sizes[t] += 1
    return taken


@numba.njit(cache=True)
def _rebuild(
    table_keys,
    counts,
    starts,
    pool,
    masks,
    new_size,
    pending,
    sub_lo,
    sub_hi,
    divisions,
    coarse,
    bits,
):  # pragma: no cover - compiled
    """A table and a compact pool holding every entry of the old ones, with room in each
    cell's block for the entries of `pending` kernels (still to be listed) and a quarter more:
    (keys, starts, counts, capacities, pool, masks, pool entries in use, slots taken). new_size:
    slots enough for every old cell and every pending entry."""
    # Distinct cells first, in a table large enough for every entry: the new table holds four
    # times as many slots as there are cells, so it can take as many again before a rebuild.
    listed = (table_keys, counts, pending, sub_lo, sub_hi, divisions, coarse, bits)
    scratch = np.full(new_size, EMPTY_KEY, dtype=np.int64)
    distinct = _place_cells(scratch, np.zeros(new_size, dtype=np.int32), *listed)
    new_size = 64
    while new_size < 4 * distinct:
        new_size *= 2
    keys = np.full(new_size, EMPTY_KEY, dtype=np.int64)
    new_starts = np.zeros(new_size, dtype=np.int64)
    new_counts = np.zeros(new_size, dtype=np.int32)
    capacities = np.zeros(new_size, dtype=np.int32)
    taken = _place_cells(keys, capacities, *listed)
    end = 0
    for t in range(new_size):
        if keys[t] != EMPTY_KEY:
            capacities[t] = max(_MIN_BLOCK, capacities[t] + capacities[t] // 4)
            new_starts[t] = end
            end += capacities[t]
    new_pool = np.empty(end + end // 4, dtype=np.int32)
    new_masks = np.empty(len(new_pool), dtype=np.uint64)
    for s in range(len(table_keys)):
        if table_keys[s] != EMPTY_KEY and counts[s] > 0:
            t = hash_slot(keys, table_keys[s])
            old = slice(starts[s], starts[s] + counts[s])
            new = slice(new_starts[t], new_starts[t] + counts[s])
            new_pool[new] = pool[old]
            new_masks[new] = masks[old]
            new_counts[t] = counts[s]
    return keys, new_starts, new_counts, capacities, new_pool, new_masks, end, taken


@numba.njit(cache=True, inline="always")
def _slot_of(points, i, scale, table):  # pragma: no cover - compiled
    """The table slot of point i's cell of `scale` (0 fine, 1 coarse; the empty slot where the
    cell lists none), whether it lists any, and the index of the point's sub-cell in it.
    table: SupportHash._arguments()."""
    keys, _, _, _, _, sub_sides, divisions, bits = table
    key, index = _cell_of(points, i, sub_sides[scale], divisions, bits, scale)
    s = hash_slot(keys, key)
    return s, keys[s] != EMPTY_KEY, index


@numba.njit(cache=True, parallel=True)
def _scale_keys(points, table):  # pragma: no cover - compiled
    """(2, n) int64 >= 0, per scale (0 fine, 1 coarse) the sub-cell of each point, read by
    _block: 1 + the table slot of its cell times the sub-cells of a cell + the sub-cell's
    index, 0 where the point's cell lists no kernel. Points whose keys match share their
    candidate kernels."""
    n = points.shape[0]
    sub_cells = np.int64(1) << SUBCELL_BITS
    found = np.empty((2, n), dtype=np.int64)
    for i in numba.prange(n):
        for scale in range(2):
            s, listed, index = _slot_of(points, i, scale, table)
            found[scale, i] = 1 + s * sub_cells + index if listed else 0
    return found


@numba.njit(cache=True, nogil=True)
def _sub_cell_groups(keys, n_slots):  # pragma: no cover - compiled
    """Points grouped by their pair of sub-cells, keys (2, n) int64 from _scale_keys on a table
    of n_slots slots, cell by cell: the groups in the order of their coarse cell's slot, then
    their fine cell's, then as they first come, so that groups taken one after the other
    share kernels still in cache. (starts, order) as rows_by_rank gives them."""
    n = keys.shape[1]
    low_bits = np.int64((1 << SUBCELL_BITS) - 1)
    # A pair of cells, numbered: (key + low_bits) >> SUBCELL_BITS is 0 for key 0 (no cell),
    # else 1 + the cell's slot.
    cells = np.empty(n, dtype=np.int64)
    for i in range(n):
        fine = (keys[0, i] + low_bits) >> SUBCELL_BITS
        cells[i] = ((keys[1, i] + low_bits) >> SUBCELL_BITS) * (n_slots + 1) + fine
    order = radix_order(cells)
    # Within a pair of cells, the keys' low bits tell their sub-cells apart; the pair of cells
    # last seen with a pair of sub-cells marks whether it has a group in this one yet.
    cells_of_pair = np.full(1 << (2 * SUBCELL_BITS), -1, dtype=np.int64)
    group_of_pair = np.empty(1 << (2 * SUBCELL_BITS), dtype=np.int64)
    group_of_row = np.empty(n, dtype=np.int64)
    n_groups = 0
    for j in range(n):
        i = order[j]
        pair = ((keys[0, i] & low_bits) << SUBCELL_BITS) | (keys[1, i] & low_bits)
        if cells_of_pair[pair] != cells[i]:
            cells_of_pair[pair] = cells[i]
            group_of_pair[pair] = n_groups
            n_groups += 1
        group_of_row[i] = group_of_pair[pair]
    return rows_by_rank(group_of_row, n_groups)


def sub_cell_groups_reference(keys: np.ndarray, n_slots: int) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of _sub_cell_groups: the distinct pairs of keys (2, n) int64, ordered
    by their pair of cells and then by their first row, and the rows sorted stably by them."""
    low_bits = (1 << SUBCELL_BITS) - 1
    cells = ((keys[1] + low_bits) >> SUBCELL_BITS) * (n_slots + 1)
    cells += (keys[0] + low_bits) >> SUBCELL_BITS
    _, pair_of_row = np.unique(keys, axis=1, return_inverse=True)
    pair_of_row = pair_of_row.ravel()
    first_row = np.full(pair_of_row.max(initial=-1) + 1, keys.shape[1])
    np.minimum.at(first_row, pair_of_row, np.arange(keys.shape[1]))
    group_of_pair = np.empty(len(first_row), dtype=np.int64)
    group_of_pair[np.lexsort((first_row, cells[first_row]))] = np.arange(len(first_row))
    group_of_row = group_of_pair[pair_of_row]
    starts = np.zeros(len(first_row) + 1, dtype=np.int64)
    np.cumsum(np.bincount(group_of_row, minlength=len(first_row)), out=starts[1:])
    return starts, np.argsort(group_of_row, kind="stable")


@numba.njit(cache=True, inline="always")
def _block(key, table):  # pragma: no cover - compiled
    """(first, last + 1) positions in the pool of the kernels listed in the cell of a
    sub-cell's key (_scale_keys), empty for key 0, and the sub-cell's selector: 1 + the index
    of its bit in their masks (_selects). table: SupportHash._arguments()."""
    starts, counts = table[1], table[2]
    if key == 0:
        return 0, 0, 0
    s = (key - 1) >> SUBCELL_BITS
    return starts[s], starts[s] + counts[s], 1 + ((key - 1) & ((1 << SUBCELL_BITS) - 1))


@numba.njit(cache=True, inline="always")
def _selects(mask, selector):  # pragma: no cover - compiled
    """Whether a kernel whose sub-cells are the bits of `mask` reaches the sub-cell of
    `selector` (_block; 0 selects every kernel)."""
    if selector == 0:
        return True
    return (mask >> np.uint64(selector - 1)) & np.uint64(1) != 0


@numba.njit(cache=True, parallel=True)
def _candidate_counts(keys, table):  # pragma: no cover - compiled
    """(u,) int64 kernels listed in each of the sub-cells `keys` (u,) int64 (_scale_keys): a
    bound on the features of that scale of a point in it."""
    masks = table[4]
    found = np.zeros(len(keys), dtype=np.int64)
    for u in numba.prange(len(keys)):
        first, end, selector = _block(keys[u], table)
        for j in range(first, end):
            found[u] += _selects(masks[j], selector)
    return found


@numba.njit(cache=True, parallel=True)
def _candidates(keys, bound, table):  # pragma: no cover - compiled
    """(bound[u],) int32 rows, as the pool keeps them, of the kernels listed in each of the
    sub-cells `keys` (u,) int64, sub-cell u's from bound[u] on (see _candidate_counts).
    Written without a branch on the masks: each entry is written and kept by moving on or not
    (past the sub-cell's last one, nothing is written)."""
    pool, masks = table[3], table[4]
    rows = np.empty(bound[len(keys)], dtype=np.int32)
    for u in numba.prange(len(keys)):
        out = bound[u]
        first, end, selector = _block(keys[u], table)
        for j in range(first, end):
            if out < bound[u + 1]:
                rows[out] = pool[j]
            out += _selects(masks[j], selector)
    return rows


@numba.njit(cache=True)
def _block_ranges(keys, table):  # pragma: no cover - compiled
    """(u, 6) int64 ranges, as _list_pass reads them, of the sub-cells (fine, coarse) of each
    of keys (2, u) int64 (_scale_keys): the blocks of the pool that list their cells' kernels,
    with the sub-cells' selectors (_block)."""
    ranges = np.empty((keys.shape[1], 6), dtype=np.int64)
    for u in range(keys.shape[1]):
        for scale in range(2):
            first, end, selector = _block(keys[scale, u], table)
            ranges[u, 2 * scale] = first
            ranges[u, 2 * scale + 1] = end
            ranges[u, 4 + scale] = selector
    return ranges


# Parts the groups of points sharing a list are split into, for the threads to share: each
# part lays its lists out in buffers of its own, made once.
_LIST_PARTS = 64
# Points a list must serve to be laid out along itself first (_gather_list); fewer project
# onto its kernels one by one, as most lists serve only a few points.
_LAID_OUT_POINTS = 4


@numba.njit(cache=True, inline="always")
def _gather_list(first, last, lists, means, transforms, planar, laid_out):  # pragma: no cover
    """The kernels lists[first:last] laid out for _list_codes in the first last - first
    columns of laid_out (13, L): each kernel's mean in rows 0-2, its transform's rows in 3-11
    (row a, column b in row 3 + 3 a + b) and in row 12 whether it is planar. A 2D kernel is
    laid out as a 3D one whose third axis is zero: the sums then add zeros and are the same."""
    d = means.shape[1]
    if d < 3:
        laid_out[:, : last - first] = 0.0
    for t in range(last - first):
        m = lists[first + t]
        laid_out[12, t] = planar[m]
        for a in range(d):
            laid_out[a, t] = means[m, a]
            for b in range(d):
                laid_out[3 + 3 * a + b, t] = transforms[m, a, b]


@numba.njit(cache=True, inline="always")
def _list_codes(points, i, n, laid_out, codes):  # pragma: no cover - compiled
    """Kernel codes of point i at the first n kernels of a list laid out by _gather_list,
    into codes[:n]. One loop along the list, in vector registers, summing in the order of
    ehm.core.model.kernels.projected_radii: the codes are kernel_code's to the last bit."""
    x = (points[i, 0], points[i, 1], points[i, 2] if points.shape[1] == 3 else 0.0)
    for t in range(n):
        r2 = 0.0
        r_max = 0.0
        for a in range(3):
            u = 0.0
            for b in range(3):
                u += laid_out[3 + 3 * a + b, t] * (x[b] - laid_out[b, t])
            r2 += u * u
            r_max = max(r_max, abs(u))
        codes[t] = kernel_code(r2, r_max, laid_out[12, t] != 0.0)


@numba.njit(cache=True, inline="always")
def _point_codes(
    points, i, first, last, lists, means, transforms, planar, codes
):  # pragma: no cover
    """Kernel codes of point i at the kernels lists[first:last], one after another, into
    codes[:last - first]."""
    for t in range(last - first):
        m = lists[first + t]
        r2, r_max = projected_radii(points, i, m, means, transforms)
        codes[t] = kernel_code(r2, r_max, planar[m])


# What a pass over the points that share lists of candidates does at each point (_list_pass):
# write the rows and codes of the kernels not zero there, or add up the log-odds.
_GATHER, _SUM = 0, 1


@numba.njit(cache=True, inline="always")
def _take_list(lists, masks, first, last, selector, kernels, n):  # pragma: no cover - compiled
    """Append lists[first:last] to kernels[:n], all of it where `selector` is 0, else the
    entries whose masks it selects (a sub-cell's kernels from its cell's block of the pool,
    _selects); returns the new length."""
    if selector == 0:
        kernels[n : n + last - first] = lists[first:last]
        return n + last - first
    for j in range(first, last):
        kernels[n] = lists[j]
        n += _selects(masks[j], selector)
    return n


@numba.njit(cache=True, parallel=True)
def _list_pass(
    points,
    order,
    starts,
    ranges,
    lists,
    masks,
    means,
    transforms,
    planar,
    mode,
    counts,
    slots,
    rows,
    codes,
    learned,
    scores,
    variance_sums,
):  # pragma: no cover - compiled
    """One pass over the points, where the points order[starts[g]:starts[g + 1]] share the
    candidate kernels of lists[ranges[g, 0]:ranges[g, 1]] (fine) and lists[ranges[g, 2]:
    ranges[g, 3]] (coarse) (starts[0] = 0): all of them where the selectors ranges[g, 4]
    (fine) and ranges[g, 5] (coarse) are 0, else those whose masks they select. At the point
    i = order[j], `mode` says what to do:
    - _GATHER: the rows and codes of the kernels not zero there into rows and codes, from
      slots[j] on (room for all its candidates) in the order of the candidates, and their
      number into counts[j] (j over order);
    - _SUM: scores[i] = bias + sum_m w_m phi_m and, with variance, [sum_m phi_m^2 /
      lambda_m, sum_m phi_m] into variance_sums (n, 2), zeros before; learned: (weights (M,),
      bias, inverse_precision (M,), with_variance). The sums are those over the kernels not
      zero, in the order of the candidates, to the last bit."""
    weights, bias, inverse_precision, with_variance = learned
    n_groups = len(starts) - 1
    for part in numba.prange(_LIST_PARTS):
        group_lo = n_groups * part // _LIST_PARTS
        group_hi = n_groups * (part + 1) // _LIST_PARTS
        longest = 0
        for g in range(group_lo, group_hi):
            longest = max(longest, ranges[g, 1] - ranges[g, 0] + ranges[g, 3] - ranges[g, 2])
        laid_out = np.empty((13, longest))
        scratch = np.empty(longest)
        kernels = np.empty(longest, dtype=lists.dtype)
        for g in range(group_lo, group_hi):
            n = _take_list(lists, masks, ranges[g, 0], ranges[g, 1], ranges[g, 4], kernels, 0)
            n = _take_list(lists, masks, ranges[g, 2], ranges[g, 3], ranges[g, 5], kernels, n)
            laid = starts[g + 1] - starts[g] >= _LAID_OUT_POINTS
            if laid:
                _gather_list(0, n, kernels, means, transforms, planar, laid_out)
            for j in range(starts[g], starts[g + 1]):
                i = order[j]
                if laid:
                    _list_codes(points, i, n, laid_out, scratch)
                else:
                    _point_codes(points, i, 0, n, kernels, means, transforms, planar, scratch)
                if mode == _GATHER:
                    # Each candidate written, and kept by moving on or not: no branch.
                    out = slots[j]
                    for t in range(n):
                        rows[out] = kernels[t]
                        codes[out] = scratch[t]
                        out += scratch[t] < OUTSIDE
                    counts[j] = out - slots[j]
                else:
                    kernels_of_codes_serial(scratch[:n])
                    scores[i] = bias
                    for t in range(n):
                        if scratch[t] != 0.0:
                            add_to_sums(
                                scores,
                                variance_sums,
                                i,
                                kernels[t],
                                scratch[t],
                                weights,
                                inverse_precision,
                                with_variance,
                            )


# Points a query takes at once, which bounds the memory of their keys and groups.
CHUNK = 65_536


# Candidates one chunk of SupportHash.features evaluates at once: the room they are written
# in (16 MB) serves chunk after chunk.
_CHUNK_CANDIDATES = 1 << 20


def _chunk_bounds(before: np.ndarray, size: int) -> np.ndarray:
    """(c + 1,) int64 bounds, in lists, of chunks of about `size` candidates (more where one
    list's points alone have more): before (G + 1,) int64, the candidates of the points of
    the lists before each list, and of all last."""
    cuts = np.searchsorted(before, np.arange(size, before[-1], size), side="right") - 1
    return np.unique(np.concatenate([[0], cuts, [len(before) - 1]]))


def _packed(
    rows: np.ndarray, codes: np.ndarray, slots: np.ndarray, counts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The counts[j] rows and codes written from slots[j] on for each point j, packed one
    point after the other: (rows (k,) int64, codes (k,) float64, and (p,) int64 where each
    point's rows begin)."""
    first = np.cumsum(counts) - counts
    total = int(counts.sum())
    packed_rows, packed_codes = np.empty(total, dtype=np.int64), np.empty(total)
    copy_segments(rows, codes, slots, counts, first, packed_rows, packed_codes)
    return packed_rows, packed_codes, first


@numba.njit(cache=True, parallel=True)
def copy_segments(
    rows, codes, sources, counts, targets, out_rows, out_codes
):  # pragma: no cover - compiled
    """For each k, copy counts[k] entries of rows (int64) and codes (float64) from sources[k]
    on into out_rows and out_codes from targets[k] on."""
    for k in numba.prange(len(counts)):
        for t in range(counts[k]):
            out_rows[targets[k] + t] = rows[sources[k] + t]
            out_codes[targets[k] + t] = codes[sources[k] + t]


def copy_segments_reference(
    rows: np.ndarray,
    codes: np.ndarray,
    sources: np.ndarray,
    counts: np.ndarray,
    targets: np.ndarray,
    out_rows: np.ndarray,
    out_codes: np.ndarray,
) -> None:
    """Plain NumPy twin of `copy_segments`."""
    within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    source, target = np.repeat(sources, counts) + within, np.repeat(targets, counts) + within
    out_rows[target], out_codes[target] = rows[source], codes[source]


# Each support box's half sides are widened by this share: a box computed in floating point
# then holds every point at which its kernel, computed likewise, is not zero.
_BOX_SLACK = 1e-9


def support_boxes(
    means: np.ndarray, transforms: np.ndarray, planar: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(M, d) lower and upper corners, metres, of the box around each kernel's support
    (ehm.core.model.kernels.support_half_widths, widened by _BOX_SLACK), for kernels of
    `means` (M, d) metres, `transforms` (M, d, d) 1/m and `planar` (M,) bool."""
    half = support_half_widths(transforms, planar) * (1.0 + _BOX_SLACK)
    return means - half, means + half


class SupportHash:
    """Every kernel of a map listed in the cells of a hash its support overlaps (see module
    docstring). dim: 2 or 3; sides: (fine, coarse) cell sides, metres."""

    def __init__(self, dim: int, sides: tuple[float, float]) -> None:
        self.dim = dim
        self.sides = np.array(sides, dtype=np.float64)
        self.divisions = 2 ** (SUBCELL_BITS // dim)
        self.bits = axis_bits(dim)
        self._slabs = sub_cell_slabs(dim, self.divisions)
        self._used = np.zeros(2, dtype=np.int64)  # pool entries to the end, table slots taken
        self._table = self._empty_table(64)
        self._pool = np.zeros(256, dtype=np.int32)
        self._masks = np.zeros(256, dtype=np.uint64)
        # Each kernel's box in sub-cells, [lo, hi] per axis; its cells are these over divisions.
        self._sub_lo = np.zeros((0, dim), dtype=np.int32)
        self._sub_hi = np.zeros((0, dim), dtype=np.int32)
        self._coarse = np.zeros(0, dtype=bool)
        self._listed = np.zeros(0, dtype=bool)

    @classmethod
    def of_radii(cls, dim: int, cluster_radius: float, free_cluster_radius: float) -> SupportHash:
        """An empty hash with cells CELL_FACTORS times each scale's cluster radius."""
        fine, coarse = CELL_FACTORS
        return cls(dim, (fine * cluster_radius, coarse * free_cluster_radius))

    @staticmethod
    def _empty_table(size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        keys = np.full(size, EMPTY_KEY, dtype=np.int64)
        # Keys and starts in the pool, then each block's entries and room (int32: a block
        # lists the kernels of one cell).
        return (
            keys,
            np.zeros(size, dtype=np.int64),
            np.zeros(size, dtype=np.int32),
            np.zeros(size, dtype=np.int32),
        )

    @property
    def nbytes(self) -> int:
        arrays = [
            *self._table,
            self._pool,
            self._masks,
            self._sub_lo,
            self._sub_hi,
            self._coarse,
            self._listed,
        ]
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
        rows = sorted_distinct(np.asarray(rows, dtype=np.int64))
        listed = rows[self._listed[rows]]
        keys, starts, counts, _ = self._table
        _remove(
            keys,
            starts,
            counts,
            self._pool,
            self._masks,
            listed,
            self._sub_lo,
            self._sub_hi,
            self.divisions,
            self._coarse,
            self.bits,
        )
        low, high = support_boxes(means[rows], transforms[rows], planar[rows])
        sub_side = self._sub_sides[coarse[rows].astype(np.int64)][:, None]
        sub_lo, sub_hi = np.floor(low / sub_side), np.floor(high / sub_side)
        # Within the keys' cells, and within the int32 the sub-cells are kept in.
        limit = min(2.0 ** (self.bits - 1) * self.divisions, 2.0**31 - self.divisions)
        if len(rows) and not (sub_lo.min() >= -limit and sub_hi.max() < limit):
            reach = limit * self._sub_sides[0]
            raise InputError(
                f"a kernel reaches more than {reach:.0f} m from the map's origin, beyond the "
                "cells of the support hash"
            )
        self._sub_lo[rows], self._sub_hi[rows] = sub_lo, sub_hi
        self._coarse[rows] = coarse[rows]
        self._listed[rows] = True
        pending = rows
        while len(pending):
            done = _insert(
                *self._table,
                self._pool,
                self._masks,
                self._used,
                pending,
                self._sub_lo,
                self._sub_hi,
                self.divisions,
                self._coarse,
                self.bits,
                self._slabs,
            )
            pending = pending[done:]
            if len(pending):
                self._make_room(pending)

    def _grow_kernels(self, n: int) -> None:
        old = len(self._listed)
        if n <= old:
            return
        size = max(n, 2 * old, 64)
        for name in ("_sub_lo", "_sub_hi", "_coarse", "_listed"):
            array = getattr(self, name)
            grown = np.zeros((size, *array.shape[1:]), dtype=array.dtype)
            grown[:old] = array
            setattr(self, name, grown)

    def _make_room(self, pending: np.ndarray) -> None:
        """Rebuild the table (at most half full once `pending` kernels are listed) and a
        compact pool whose blocks have room for the pending kernels' entries."""
        lo, hi = self._sub_lo[pending] // self.divisions, self._sub_hi[pending] // self.divisions
        cells = int(np.prod(hi - lo + 1, axis=1).sum())
        keys, starts, counts, _ = self._table
        size = len(keys)
        while 2 * (self._used[1] + cells) > size:
            size *= 2
        *table, pool, masks, end, taken = _rebuild(
            keys,
            counts,
            starts,
            self._pool,
            self._masks,
            size,
            pending,
            self._sub_lo,
            self._sub_hi,
            self.divisions,
            self._coarse,
            self.bits,
        )
        self._table, self._pool, self._masks = tuple(table), pool, masks
        self._used[:] = end, taken

    # -------------------------------------------------------------- queries
    @property
    def _sub_sides(self) -> np.ndarray:
        """(2,) metres: the side of a sub-cell of each scale."""
        return self.sides / self.divisions

    def _arguments(self) -> tuple:
        """What the compiled queries read: (keys, starts, counts, pool, masks, sub-cell sides,
        sub-cells per axis, bits per axis of a key)."""
        keys, starts, counts, _ = self._table
        return (
            keys,
            starts,
            counts,
            self._pool,
            self._masks,
            self._sub_sides,
            self.divisions,
            self.bits,
        )

    def _groups(self, points: np.ndarray) -> tuple:
        """(n, d) points grouped by the sub-cells they lie in at both scales
        (_sub_cell_groups): (table, as _arguments gives it; order; starts; the keys (2, G)
        int64 of each group's sub-cells)."""
        table = self._arguments()
        keys = _scale_keys(points, table)
        starts, order = _sub_cell_groups(keys, len(table[0]))
        return table, order, starts, np.ascontiguousarray(keys[:, order[starts[:-1]]])

    def _shared_lists(self, points: np.ndarray) -> tuple:
        """(n, d) points grouped by their sub-cells (_groups), each group with the two lists
        (fine, coarse) of candidate kernels its points share: (order, starts, ranges (G, 6)
        int64, lists, masks), as _list_pass reads them. Each scale's list of a sub-cell is
        made once, for every group that lies in it."""
        table, order, starts, group_keys = self._groups(points)
        ranges = np.zeros((len(starts) - 1, 6), dtype=np.int64)
        lists, offset = [], 0
        for scale in range(2):
            sub_cell_of_group, n_sub_cells = first_come_ranks(group_keys[scale])
            sub_cells = np.empty(n_sub_cells, dtype=np.int64)
            sub_cells[sub_cell_of_group] = group_keys[scale]
            bound = np.zeros(n_sub_cells + 1, dtype=np.int64)
            np.cumsum(_candidate_counts(sub_cells, table), out=bound[1:])
            lists.append(_candidates(sub_cells, bound, table))
            ranges[:, 2 * scale] = bound[sub_cell_of_group] + offset
            ranges[:, 2 * scale + 1] = bound[sub_cell_of_group + 1] + offset
            offset += bound[-1]
        return order, starts, ranges, np.concatenate(lists), np.zeros(0, dtype=np.uint64)

    def _shared_blocks(self, points: np.ndarray) -> tuple:
        """(n, d) points grouped by their sub-cells (_groups), each group with the blocks of
        the pool that list its cells' kernels and the selectors of its sub-cells: (order,
        starts, ranges (G, 6) int64, pool, masks), as _list_pass reads them. No list is made:
        a pass that reads each list once sifts the blocks itself."""
        table, order, starts, group_keys = self._groups(points)
        return order, starts, _block_ranges(group_keys, table), self._pool, self._masks

    def features(
        self, points: np.ndarray, means: np.ndarray, transforms: np.ndarray, planar: np.ndarray
    ) -> SparseFeatures:
        """Every kernel not zero at each of (n, d) points, metres, as the points' features.

        Each point projects once onto its list's kernels. The points are taken list after
        list in chunks of about _CHUNK_CANDIDATES candidates, whose kernels not zero are
        packed chunk by chunk and then laid out in the order of the points."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        if len(points) == 0:
            return SparseFeatures(np.zeros(1, np.int64), np.zeros(0, np.int64), np.zeros(0))
        order, starts, ranges, lists, masks = self._shared_lists(points)
        kernels = (lists, masks, means, transforms, planar)
        unsummed = ((np.zeros(0), 0.0, np.zeros(0), False), np.zeros(0), np.zeros((0, 2)))
        # Candidates of each point, in the order of the lists, and where each point's
        # candidates would begin in a room for all of them.
        listed = ranges[:, 1] - ranges[:, 0] + ranges[:, 3] - ranges[:, 2]
        candidates = np.repeat(listed, np.diff(starts))
        first_candidate = np.cumsum(candidates) - candidates
        before_list = np.append(first_candidate, candidates.sum())[starts]
        chunks = _chunk_bounds(before_list, _CHUNK_CANDIDATES)
        room = int(np.max(np.diff(before_list[chunks]), initial=0))
        room_rows, room_codes = np.empty(room, dtype=np.int64), np.empty(room)
        counts = np.empty(len(points), dtype=np.int64)  # in the order of the lists
        packed = []
        for g0, g1 in itertools.pairwise(chunks):
            chunk = slice(starts[g0], starts[g1])
            slots = first_candidate[chunk] - first_candidate[chunk.start]
            _list_pass(
                points,
                order[chunk],
                starts[g0 : g1 + 1] - chunk.start,
                ranges[g0:g1],
                *kernels,
                _GATHER,
                counts[chunk],
                slots,
                room_rows,
                room_codes,
                *unsummed,
            )
            packed.append((chunk, *_packed(room_rows, room_codes, slots, counts[chunk])))
        point_counts = np.empty(len(points), dtype=np.int64)
        point_counts[order] = counts
        indptr = np.zeros(len(points) + 1, dtype=np.int64)
        np.cumsum(point_counts, out=indptr[1:])
        rows, values = np.empty(indptr[-1], dtype=np.int64), np.empty(indptr[-1])
        for chunk, *chunk_packed in packed:
            copy_segments(*chunk_packed, counts[chunk], indptr[order[chunk]], rows, values)
        kernels_of_codes(values)
        return SparseFeatures(indptr, rows, values)

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
        with_variance, their (n, 2) variance sums [sum_m phi_m^2 / lambda_m, sum_m phi_m]
        (else (0, 2)), in one pass over the points' kernels."""
        points = np.ascontiguousarray(points, dtype=np.float64)
        scores = np.empty(len(points))
        variance_sums = np.zeros((len(points) if with_variance else 0, 2))
        none, nothing = np.zeros(0, dtype=np.int64), np.zeros(0)
        learned = (weights, float(bias), inverse_precision, with_variance)
        for first in range(0, len(points), CHUNK):
            chunk = slice(first, min(len(points), first + CHUNK))
            _list_pass(
                points[chunk],
                *self._shared_blocks(points[chunk]),
                means,
                transforms,
                planar,
                _SUM,
                none,
                none,
                none,
                nothing,
                learned,
                scores[chunk],
                variance_sums[chunk],
            )
        return scores, variance_sums


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
