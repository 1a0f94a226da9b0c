"""Rays that pass through old occupied evidence: where a batch's rays show free space that the
memory (ehm.core.observations.memory) holds occupied.

A ray passes an occupied entry when, along the free part of the ray (ScanRays.free_start to
free_end: up to `surface_margin` before its hit) and short of its hit by more than the band a
surface is taken to be solid, it goes through the entry's region and comes within `reach`
metres of the entry's mean, widened where the rays of its scan lie farther apart than that
(ehm.core.sensor.ray_spacing, `pass_reach`): noise and rays that end on the surface they graze
do not pass it, and the rings of a sparse LiDAR, whose gaps grow with range, pass the old faces
that lie between them.
The band is `occupied_depth` deep and grows with the square of the ray's length, as a depth
camera's range noise does (BAND_GROWTH). Within that band, a ray whose hit lies on a plane of
the batch's own hits (the floor behind a cart that left) passes the entries that lie off the
plane: the cart's lowest centimetres, which rays to the floor behind it reach only within the
band. An entry the batch hits again stays: one in whose cell a new hit lands, or near whose
mean one does (`hit_again`), within the lateral shift a small error in the sensor's
orientation gives at its range (REGISTRATION_SLACK): a surface seen from a pose a degree off
stands beside where it stood, and the rays past its edge go through its old place; rays
that run along a surface still there, whose hits land on it, pass it no more than that.
Each ray walks the regions it crosses (a 3D DDA on the grid of regions,
ehm.core.primitives.grid_walk), tests each in a bitmap of the regions that hold occupied entries,
and looks up only those in the table of the memory's regions. Where a scan's rays lie so close
that dozens pass each entry (a depth camera's a few metres from a wall), only a share of them
walk, each pass counting for the rays its ray stands for (`walked_rays`): as many passes in
expectation, found in a fraction of the time.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from itertools import repeat

import numba
import numpy as np
from scipy.spatial import cKDTree

from ehm.core.observations.evidence import FINE_CELLS_PER_RADIUS, OCCUPIED
from ehm.core.observations.memory import OFFSET_STEPS, EvidenceMemory
from ehm.core.observations.memory_keys import SUB_BITS, region_bits
from ehm.core.observations.samples import ScanRays
from ehm.core.primitives.cells import in_neighbour_cells
from ehm.core.primitives.grid_walk import walk_setup, walk_step
from ehm.core.primitives.hashing import row_of
from ehm.core.search.index import PARALLEL_SEARCH_POINTS

# How close a ray must come to an entry's mean to pass it, in fine evidence cells (3 cm at 5 cm
# of detail).
PASS_REACH_CELLS = 1.0
# Where its scan's rays lie farther apart than `reach` at an entry's distance along a ray,
# the ray reaches this many times that gap: about the gap between the rings of a spinning
# LiDAR, whose ray spacing (the geometric mean of its gaps) is 0.9 degrees on 16 beams with
# rings 2 apart. With a cell's reach alone, a third to two thirds of a departed cart's old
# faces, between the rings of 16- and 32-beam LiDARs, still read occupied six scans after it
# left. Rays closer than `reach`, a depth camera's (0.2 degrees apart), keep it: widened there
# too, passes by rays beside surfaces still there took their evidence back.
PASS_REACH_WIDENING = 2.0
# Within the band behind which a hit's surface is taken to be solid, a ray passes the entries
# farther than this from the plane of its batch's hits around its hit, in fine evidence cells:
# a departed object's old faces then fade, where the band would shield them.
OFF_PLANE_CELLS = 1.5
# The solid band in front of a hit grows by this many metres per square metre of the ray's
# length: at 2 m it is `occupied_depth` and 16 cm deep, at 5 m a metre more. Depth cameras'
# range noise grows with the square of range, and far walls seen by one frame would otherwise
# be passed by the next.
BAND_GROWTH = 0.04
# A batch's hit within this share of its range of an entry's mean (0.02: the lateral shift of
# about a degree of orientation error), or within `reach`, keeps the entry from being passed.
REGISTRATION_SLACK = 0.02
# Where a dense sensor's rays lie closer together than a pass's reach, an entry they pass lies
# within reach of many of them (a depth camera's frame: 40 to 110 rays at 2 m); passes are then
# found along a share of the rays, about WALKED_PER_ENTRY within reach of each entry, each pass
# counting for the rays its ray stands for. The walked rays follow a low-discrepancy sequence
# over the rays' order (WALK_SEQUENCE, the golden ratio's fraction), spread evenly over a frame.
# With 8, the places a person walked through before a depth camera kept half as much again of
# their evidence.
WALKED_PER_ENTRY = 16.0
WALK_SEQUENCE = (np.sqrt(5.0) - 1.0) / 2.0
# Rays a batch must have before its passes are found in PASS_PARTS parts of its rays, shared
# by as many threads as there are. A frame's rows of rays differ in length and in the memory
# they cross, so more parts than threads share the work more evenly.
PARALLEL_MIN_RAYS = 2_000
PASS_PARTS = 8
# Regions a bitmap of the regions that hold occupied entries may span (2^28 bits, 32 MB): a ray
# tests each region it walks in the bitmap and looks up only those it holds (a small share of
# its steps). A box of more regions goes without, and every step is looked up.
BITMAP_REGIONS = 1 << 28
# Regions one thread lays out at a time.
CHUNK = 1024
# Cells around an entry `hit_again` marks before it searches only the hits in them: where the
# entries are so many that their cells would outnumber the hits, it searches all.
NEIGHBOUR_CELLS = 27


@numba.njit(cache=True, nogil=True)
def occupied_bitmap(regions, occupied_starts, bits, dim):  # pragma: no cover - compiled
    """The memory's regions that hold occupied entries (`regions` (R,) int64,
    EvidenceMemory.regions; occupied_starts (R + 1,), occupied_layout's), as bits over their
    box: (low (d,) int64, the box's least region; extent (d,) int64, regions along each axis,
    zeros for none; words (W,) uint64, bit i set for the region at low + the row-major index
    i, none where the box spans more than BITMAP_REGIONS)."""
    half = np.int64(1) << (bits - 1)
    axis_mask = (np.int64(1) << bits) - 1
    low = np.full(dim, np.iinfo(np.int64).max, dtype=np.int64)
    high = np.full(dim, np.iinfo(np.int64).min, dtype=np.int64)
    coordinates = np.empty((len(regions), dim), dtype=np.int64)
    for r in range(len(regions)):
        packed = regions[r] >> 1
        for a in range(dim - 1, -1, -1):
            coordinates[r, a] = (packed & axis_mask) - half
            packed >>= bits
        if occupied_starts[r + 1] > occupied_starts[r]:
            for a in range(dim):
                low[a] = min(low[a], coordinates[r, a])
                high[a] = max(high[a], coordinates[r, a])
    extent = np.maximum(high - low + 1, 0)
    volume = 1.0
    for a in range(dim):
        volume *= extent[a]
    if volume == 0 or volume > BITMAP_REGIONS:
        return low, extent, np.zeros(0, dtype=np.uint64)
    words = np.zeros((int(volume) + 63) // 64, dtype=np.uint64)
    for r in range(len(regions)):
        if occupied_starts[r + 1] > occupied_starts[r]:
            index = np.int64(0)
            for a in range(dim):
                index = index * extent[a] + coordinates[r, a] - low[a]
            words[index >> 6] |= np.uint64(1) << np.uint64(index & 63)
    return low, extent, words


@numba.njit(cache=True, inline="always")
def _holds_occupied(region, low, extent, words):  # pragma: no cover - compiled
    """Whether `region` (d,) int64 may hold occupied entries: in the bitmap of occupied_bitmap
    (low, extent, words), or any region where it has no words."""
    if len(words) == 0:
        return True
    index = np.int64(0)
    for a in range(len(region)):
        offset = region[a] - low[a]
        if offset < 0 or offset >= extent[a]:
            return False
        index = index * extent[a] + offset
    return (words[index >> 6] >> np.uint64(index & 63)) & np.uint64(1) != 0


@numba.njit(cache=True, inline="always")
def _entry_position(region, cell, place, fine_side, position):  # pragma: no cover - compiled
    """The mean of an entry (its `cell` byte and `place` (d,) uint8) in integer `region` (d,),
    metres, into `position` (d,)."""
    d = len(region)
    sub = cell & ((1 << SUB_BITS) - 1)
    for a in range(d - 1, -1, -1):
        along = sub % FINE_CELLS_PER_RADIUS
        sub //= FINE_CELLS_PER_RADIUS
        position[a] = (
            region[a] * FINE_CELLS_PER_RADIUS + along + place[a] / OFFSET_STEPS
        ) * fine_side


OccupiedLayout = tuple[np.ndarray, np.ndarray, np.ndarray]
"""The occupied entries of a memory's regions around hits, region by region, as a ray reads
them: starts (R + 1,) int64, where each region's begin in `entries` (k,) int64, their rows in
the memory; positions (k, d) float64, their means, metres."""


def occupied_layout(memory: EvidenceMemory) -> OccupiedLayout:
    """The memory's OccupiedLayout (regions along rays hold none)."""
    return _layout_kernel(
        memory.regions,
        memory.region_first(),
        memory.region_sizes,
        memory.cells,
        memory.place,
        memory.sides[0],
        region_bits(memory.dim),
    )


@numba.njit(cache=True, parallel=True)
def _layout_kernel(
    regions, region_first, region_sizes, cells, place, fine_side, bits
):  # pragma: no cover - compiled
    """occupied_layout of the memory's arrays (EvidenceMemory), `bits` an axis of a region
    key."""
    d = place.shape[1]
    n_regions = len(regions)
    starts = np.zeros(n_regions + 1, dtype=np.int64)
    for r in numba.prange(n_regions):
        if regions[r] & 1 == 0:
            for e in range(region_first[r], region_first[r] + region_sizes[r]):
                starts[r + 1] += cells[e] >> SUB_BITS >= OCCUPIED
    for r in range(n_regions):
        starts[r + 1] += starts[r]
    entries = np.empty(starts[n_regions], dtype=np.int64)
    positions = np.empty((starts[n_regions], d))
    half = np.int64(1) << (bits - 1)
    for chunk in numba.prange((n_regions + CHUNK - 1) // CHUNK):
        region = np.empty(d, dtype=np.int64)
        for r in range(chunk * CHUNK, min((chunk + 1) * CHUNK, n_regions)):
            if starts[r + 1] == starts[r]:
                continue
            packed = regions[r] >> 1
            for a in range(d - 1, -1, -1):
                region[a] = (packed & ((np.int64(1) << bits) - 1)) - half
                packed >>= bits
            k = starts[r]
            for e in range(region_first[r], region_first[r] + region_sizes[r]):
                if cells[e] >> SUB_BITS >= OCCUPIED:
                    entries[k] = e
                    _entry_position(region, cells[e], place[e], fine_side, positions[k])
                    k += 1
    return starts, entries, positions


@numba.njit(cache=True, inline="always")
def _off_plane(position, point, normal, gap):  # pragma: no cover - compiled
    """Whether `position` (d,) lies farther than `gap` metres from the plane through `point`
    (d,) of unit `normal` (d,) (NaN: no plane, and it does not)."""
    if normal[0] != normal[0]:
        return False
    distance = 0.0
    for a in range(len(normal)):
        distance += (position[a] - point[a]) * normal[a]
    return abs(distance) > gap


def pass_reach(reach: float, gap: np.ndarray | float) -> np.ndarray | float:
    """How close, metres, a ray must come to an entry to pass it: `reach`, or
    PASS_REACH_WIDENING times the `gap` to the next ray of its scan at the entry's distance
    (metres) where that is wider."""
    return np.where(gap > reach, PASS_REACH_WIDENING * gap, reach)


def _solid_band(rays: ScanRays, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """Where each ray's solid band starts (n,) (its free end for rays without a hit) and its
    hit (n, d)."""
    band = depth + BAND_GROWTH * rays.lengths**2
    solid_start = np.where(rays.hits, rays.free_end - band, rays.free_end)
    return solid_start, rays.ends


@numba.njit(cache=True, nogil=True)
def pass_kernel(
    first_ray,
    last_ray,
    origins,
    directions,
    free_start,
    free_end,
    solid_start,
    hit_points,
    hit_normals,
    plane_gap,
    table_keys,
    table_rows,
    occupied_starts,
    occupied_entries,
    positions,
    fine_side,
    reach,
    ray_spacing,
    widening,
    bits,
    bitmap,
    found,
    used,
    ray_passes,
):  # pragma: no cover - compiled
    """Append to `found` (capacity,) int64, from `used` on, the occupied entry of every pass of
    rays first_ray .. last_ray - 1 (origins, directions (n, d), free_start, free_end (n,),
    metres, ScanRays) through the memory's entries, and set ray_passes[r] (n,) int64 to the
    passes of each ray r: table_keys, table_rows from
    EvidenceMemory.region_table; occupied_starts, occupied_entries and positions from
    `occupied_layout`; ray r passes the entries within `pass_reach` of it (reach and
    widening as there, its gap ray_spacing[r] (n,) radians times their distance along it);
    `bits` an axis of a region key; bitmap: occupied_bitmap's (low, extent, words), the
    regions to look up. From solid_start (n,) on, a ray passes only entries farther than
    `plane_gap` metres from the plane through its hit, hit_points (n, d), of normal
    hit_normals (n, d) (NaN: none, and it passes none there). Stops before a ray that might
    overfill `found`; returns (the next ray, entries found)."""
    d = origins.shape[1]
    bitmap_low, bitmap_extent, bitmap_words = bitmap
    side = fine_side * FINE_CELLS_PER_RADIUS
    half = np.int64(1) << (bits - 1)
    region = np.empty(d, dtype=np.int64)
    step = np.empty(d, dtype=np.int64)
    t_next = np.empty(d)
    t_delta = np.empty(d)
    for r in range(first_ray, last_ray):
        t, t_end = free_start[r], free_end[r]
        ray_passes[r] = 0
        if t_end <= t:
            continue
        if used + 64 * (4 + int((t_end - t) / side) * d) > len(found):
            return r, used
        ray_first = used
        for a in range(d):
            region[a] = np.int64(np.floor((origins[r, a] + directions[r, a] * t) / side))
        walk_setup(origins[r], directions[r], side, region, step, t_next, t_delta)
        while t < t_end:
            if not _holds_occupied(region, bitmap_low, bitmap_extent, bitmap_words):
                t = walk_step(region, step, t_next, t_delta)
                continue
            key = np.int64(0)
            for a in range(d):
                key = (key << bits) | (region[a] + half)
            row = row_of(table_keys, table_rows, key << 1)  # the region around hits
            if row >= 0:
                for k in range(occupied_starts[row], occupied_starts[row + 1]):
                    position = positions[k]
                    along = 0.0
                    for a in range(d):
                        along += (position[a] - origins[r, a]) * directions[r, a]
                    if along <= free_start[r] or along >= t_end:
                        continue
                    if along >= solid_start[r] and not _off_plane(
                        position, hit_points[r], hit_normals[r], plane_gap
                    ):
                        continue
                    off = 0.0
                    for a in range(d):
                        gap = position[a] - origins[r, a] - along * directions[r, a]
                        off += gap * gap
                    gap = ray_spacing[r] * along
                    limit = widening * gap if gap > reach else reach
                    if off < limit * limit:
                        found[used] = occupied_entries[k]
                        used += 1
            t = walk_step(region, step, t_next, t_delta)
        ray_passes[r] = used - ray_first
    return last_ray, used


def _passes_of_part(arguments: tuple, ray_passes: np.ndarray, first: int, last: int) -> np.ndarray:
    """Occupied entries passed by rays first .. last - 1 (`arguments`: pass_kernel's from
    `origins` to `bitmap`), one row per pass, ray by ray; sets their `ray_passes`."""
    found = np.empty(max(1024, 64 * (last - first)), dtype=np.int64)
    used, ray = 0, first
    while ray < last:
        ray, used = pass_kernel(ray, last, *arguments, found, used, ray_passes)
        if ray < last:
            found = np.concatenate([found[:used], np.empty(2 * len(found), dtype=np.int64)])
    return found[:used]


def _in_parts(arguments: tuple, n: int) -> tuple[np.ndarray, np.ndarray]:
    """pass_kernel over n rays in PASS_PARTS parts on the threads there are (one part for
    fewer than PARALLEL_MIN_RAYS): the entries passed, one row per pass in the rays' order,
    and (n,) int64 the passes of each ray."""
    parts = 1 if n < PARALLEL_MIN_RAYS else PASS_PARTS
    bounds = [n * part // parts for part in range(parts + 1)]
    ray_passes = np.zeros(n, dtype=np.int64)
    with ThreadPoolExecutor(min(parts, numba.get_num_threads())) as pool:
        found = pool.map(
            _passes_of_part, repeat(arguments), repeat(ray_passes), bounds[:-1], bounds[1:]
        )
        return np.concatenate(list(found)), ray_passes


def walked_rays(rays: ScanRays, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """The rays passes are found along (WALKED_PER_ENTRY): (rows (w,) int64, weight (w,)
    float64, how many rays each stands for). A ray's share is WALKED_PER_ENTRY over the rays
    of its scan within `reach` metres of a point at its end, (2 reach / gap)^(d - 1) for the
    gap (metres) between them there, at most 1 (all rays of sparse scans, and of rays whose
    gap is unknown)."""
    gap = rays.ray_spacing * rays.lengths
    exponent = rays.directions.shape[1] - 1
    share = np.ones(len(rays))
    spaced = gap > 0.0
    share[spaced] = np.minimum(1.0, WALKED_PER_ENTRY * (gap[spaced] / (2.0 * reach)) ** exponent)
    turn = np.arange(1, len(rays) + 1) * WALK_SEQUENCE % 1.0
    rows = np.flatnonzero(turn < share)
    return rows, 1.0 / share[rows]


def occupied_passes(
    memory: EvidenceMemory, rays: ScanRays, reach: float, depth: float
) -> tuple[np.ndarray, np.ndarray]:
    """The memory's occupied entries that `rays` pass (see the module's docstring), within
    `reach` metres (widened by `pass_reach` between sparse rays), a ray with a hit only
    where it goes on for `depth` metres more (the band a surface is taken to be solid,
    `occupied_depth`), found along the `walked_rays`: (entries (k,) int64 sorted, passes (k,)
    float64 rays through each, each walked ray's pass counting for the rays it stands for)."""
    if len(memory) == 0 or len(rays) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    keys, rows = memory.region_table()
    layout = occupied_layout(memory)
    fine_side = memory.sides[0]
    walked, stands_for = walked_rays(rays, reach)
    solid_start, hit_points = _solid_band(rays, depth)
    arguments = (
        np.ascontiguousarray(rays.origins[walked]),
        rays.directions[walked],
        rays.free_start[walked],
        rays.free_end[walked],
        solid_start[walked],
        hit_points[walked],
        rays.hit_normals[walked],
        OFF_PLANE_CELLS * fine_side,
        keys,
        rows,
        *layout,
        fine_side,
        reach,
        rays.ray_spacing[walked],
        PASS_REACH_WIDENING,
        region_bits(memory.dim),
        occupied_bitmap(memory.regions, layout[0], region_bits(memory.dim), memory.dim),
    )
    found, ray_passes = _in_parts(arguments, len(walked))
    # Counted by entry rather than sorted (np.unique), which is several times faster.
    passes = np.bincount(found, np.repeat(stands_for, ray_passes))
    entries = np.flatnonzero(passes)
    return entries, passes[entries]


def hit_again(
    memory: EvidenceMemory, entries: np.ndarray, rays: ScanRays, reach: float
) -> np.ndarray:
    """(k,) bool: whether a hit of `rays` lies near the mean of each of the memory's `entries`
    (k,) int64: within `reach` metres, or within REGISTRATION_SLACK of the mean's range from
    the origin of the nearest hit's ray."""
    hits = rays.hits
    if len(entries) == 0 or not hits.any():
        return np.zeros(len(entries), dtype=bool)
    points = memory.points_at(entries)
    origin = rays.origins[0]
    if np.all(rays.origins == origin):  # one origin: no hit farther than the entries' bounds
        farthest = max(reach, REGISTRATION_SLACK * np.linalg.norm(points - origin, axis=1).max())
    else:
        farthest = REGISTRATION_SLACK * rays.lengths.max() + reach  # entries lie on the rays
    # Only hits within `farthest` of the entries' box can be any entry's nearest.
    low, high = points.min(axis=0) - farthest, points.max(axis=0) + farthest
    near_box = hits & np.all((rays.ends >= low) & (rays.ends <= high), axis=1)
    if NEIGHBOUR_CELLS * len(points) < near_box.sum():
        # Few entries (a frame that passes little): only hits in cells of `farthest` beside
        # theirs can be any one's nearest, and the tree holds those alone.
        rows = np.flatnonzero(near_box)
        beside = in_neighbour_cells(points, rays.ends[rows], farthest)
        if beside is not None:
            near_box[rows[~beside]] = False
    if not near_box.any():
        return np.zeros(len(entries), dtype=bool)
    origins, hit_points = rays.origins[near_box], rays.ends[near_box]
    tree = cKDTree(hit_points, balanced_tree=False, compact_nodes=False)  # faster to build
    workers = numba.get_num_threads() if len(points) >= PARALLEL_SEARCH_POINTS else 1
    bound = np.nextafter(farthest, np.inf)  # the search's bound is strict
    distance, nearest = tree.query(points, distance_upper_bound=bound, workers=workers)
    found = np.flatnonzero(np.isfinite(distance))
    ranges = np.linalg.norm(points[found] - origins[nearest[found]], axis=1)
    near = np.zeros(len(entries), dtype=bool)
    near[found] = distance[found] <= np.maximum(reach, REGISTRATION_SLACK * ranges)
    return near


def occupied_passes_reference(
    memory: EvidenceMemory, rays: ScanRays, reach: float, depth: float
) -> tuple[np.ndarray, np.ndarray]:
    """Plain NumPy twin of `occupied_passes`: every walked ray against every occupied entry,
    the ray's free part clipped to the entry's region by the slab test, and in the solid band
    only the entries off the plane of the batch's hits."""
    samples = memory.samples()
    entries = np.flatnonzero(samples.occupied)
    points = samples.points[entries]
    plane_gap = OFF_PLANE_CELLS * memory.sides[0]
    side = memory.sides[0] * FINE_CELLS_PER_RADIUS
    # The entry's region, which its mean may lie on the far edge of.
    cell_centres = memory.corners_at(entries) + memory.sides[0] / 2
    low = np.floor(cell_centres / side) * side
    solid_start, hit_points = _solid_band(rays, depth)
    hit_normals = rays.hit_normals
    passes = np.zeros(len(entries))
    walked, stands_for = walked_rays(rays, reach)
    for r, weight in zip(walked, stands_for, strict=True):
        o, u = rays.origins[r], rays.directions[r]
        start, end = rays.free_start[r], rays.free_end[r]
        with np.errstate(invalid="ignore"):
            off_plane = np.abs((points - hit_points[r]) @ hit_normals[r]) > plane_gap
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (low - o) / u, (low + side - o) / u
        enter = np.maximum(np.nanmax(np.minimum(t0, t1), axis=1), start)
        leave = np.minimum(np.nanmin(np.maximum(t0, t1), axis=1), end)
        along = (points - o) @ u
        off = np.linalg.norm(points - o - along[:, None] * u, axis=1)
        solid = along >= solid_start[r]
        passes += weight * (
            (enter < leave)
            & (along > start)
            & (along < end)
            & (off < pass_reach(reach, rays.ray_spacing[r] * along))
            & (~solid | off_plane)
        )
    passed = passes > 0
    return entries[passed], passes[passed]
