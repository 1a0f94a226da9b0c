"""Surface meshes of occupancy grids by marching cubes (Lorensen & Cline, 1987) over the cubes
of eight voxel centres, with a case table derived here: the surface crosses each cube edge whose
ends lie on either side of the level; on each cube face the crossings pair up into segments,
a face with four crossings cutting off each of its two occupied corners (a rule of the face
alone, so two cubes sharing a face cut it alike and the surface stays closed); the segments
close into polygons, fanned into triangles."""

from __future__ import annotations

from collections.abc import Iterable
from functools import cache

import numpy as np

from ehm.errors import InputError

# The cube's corners, (8, 3) voxel offsets: corner c at (c & 1, c >> 1 & 1, c >> 2 & 1).
CUBE_CORNERS = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])
# The cube's edges, (12, 2) corners, low corner first: four along each axis in turn.
CUBE_EDGES = np.array(
    [(c, c | 1 << axis) for axis in range(3) for c in range(8) if not c >> axis & 1]
)
# Each edge's axis: 0, 1 or 2.
EDGE_AXES = np.repeat(np.arange(3), 4)
# The cube's faces, (6, 4) corners in order around each face: the low and high face across
# each axis, walked along the next axis and then the one after.
CUBE_FACES = np.array(
    [
        [
            side << axis | u << (axis + 1) % 3 | v << (axis + 2) % 3
            for u, v in ((0, 0), (1, 0), (1, 1), (0, 1))
        ]
        for axis in range(3)
        for side in (0, 1)
    ]
)


def _cube_polygons(case: int) -> list[list[int]]:
    """The surface's polygons in a cube whose corners above the level are the bits of `case`:
    each a list of the edges it crosses, in order around it, wound so that its normal points
    from the occupied corners to the free ones."""
    inside = [bool(case >> c & 1) for c in range(8)]
    edge_of = {frozenset(map(int, e)): i for i, e in enumerate(CUBE_EDGES)}
    neighbours: dict[int, list[int]] = {}
    for face in CUBE_FACES:
        around = [edge_of[frozenset((int(face[i]), int(face[(i + 1) % 4])))] for i in range(4)]
        crossed = [i for i in range(4) if inside[face[i]] != inside[face[(i + 1) % 4]]]
        if len(crossed) == 2:
            pairs = [(around[crossed[0]], around[crossed[1]])]
        elif len(crossed) == 4:  # cut off each occupied corner: its two edges on this face
            pairs = [(around[i - 1], around[i]) for i in range(4) if inside[face[i]]]
        else:
            pairs = []
        for a, b in pairs:
            neighbours.setdefault(a, []).append(b)
            neighbours.setdefault(b, []).append(a)
    polygons, seen = [], set()
    for start in sorted(neighbours):
        if start in seen:
            continue
        polygon, previous, current = [start], None, start
        while True:
            seen.add(current)
            step = next(e for e in neighbours[current] if e != previous)
            if step == start:
                break
            polygon.append(step)
            previous, current = current, step
        polygons.append(_wound(polygon, inside))
    return polygons


def _wound(polygon: list[int], inside: list[bool]) -> list[int]:
    """`polygon` (edges), reversed if its normal (Newell's, on the edges' midpoints) points
    from free corners into occupied ones."""
    ends = CUBE_EDGES[polygon]
    points = CUBE_CORNERS[ends].mean(axis=1)
    normal = np.cross(points, np.roll(points, -1, axis=0)).sum(axis=0)
    outward = sum((CUBE_CORNERS[b] - CUBE_CORNERS[a]) * (1 if inside[a] else -1) for a, b in ends)
    return polygon if normal @ outward > 0 else polygon[::-1]


@cache
def case_table() -> tuple[np.ndarray, np.ndarray]:
    """(256, T, 3) int64 cube edges of each case's triangles, fanned from each polygon, and
    (256,) int64 how many triangles each case has. Built on first use, not at import."""
    triangles = [
        [(p[0], p[i], p[i + 1]) for p in _cube_polygons(case) for i in range(1, len(p) - 1)]
        for case in range(256)
    ]
    counts = np.array([len(t) for t in triangles], dtype=np.int64)
    table = np.zeros((256, counts.max(), 3), dtype=np.int64)
    for case, rows in enumerate(triangles):
        if rows:
            table[case, : len(rows)] = rows
    return table, counts


def marching_cubes(
    probability: np.ndarray, origin: np.ndarray, resolution: float, level: float = 0.5
) -> tuple[np.ndarray, np.ndarray]:
    """Iso-surface at `level` of a 3D grid of probabilities (nx, ny, nz) whose voxel (0, 0, 0)
    has its low corner at `origin` (3,), metres, world frame, voxels `resolution` metres wide.

    Returns vertices (V, 3) float64, metres, world frame, and faces (F, 3) int64 rows of
    `vertices`, each vertex shared by the faces around it. A face (a, b, c) is wound so that
    (b - a) x (c - a) points from occupied (p > level) into free space. Both are empty when the
    probability never crosses `level`."""
    if probability.ndim != 3:
        raise InputError(f"marching cubes needs a 3D grid, got {probability.ndim} dimensions")
    if not 0.0 < level < 1.0:
        raise InputError(f"level must be a probability between 0 and 1, got {level}")
    empty = np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    if min(probability.shape) < 2 or probability.max() <= level or probability.min() > level:
        return empty
    inside = probability > level
    _, ny, nz = probability.shape
    strides = np.array([ny * nz, nz, 1])
    # (C, 8) flat voxel indices of the corners of each cube the level crosses.
    corners = _crossed_cubes(inside)[:, None] + CUBE_CORNERS @ strides
    case = (inside.ravel()[corners] << np.arange(8)).sum(axis=1)
    case_triangles, case_counts = case_table()
    counts = case_counts[case]
    cube = np.repeat(np.arange(len(case)), counts)
    which = np.arange(len(cube)) - np.repeat(np.cumsum(counts) - counts, counts)
    edges = case_triangles[case[cube], which]  # (F, 3) cube edges
    # One vertex per crossed grid edge (its low end and axis), shared by the faces meeting it.
    edge_keys = corners[cube[:, None], CUBE_EDGES[edges, 0]] * 3 + EDGE_AXES[edges]
    crossed = np.zeros(3 * probability.size, dtype=bool)
    crossed[edge_keys] = True
    unique_edges = np.flatnonzero(crossed)
    faces = np.searchsorted(unique_edges, edge_keys)
    inner, axis = np.divmod(unique_edges, 3)
    outer = inner + strides[axis]
    values = probability.ravel()
    # Each edge from its occupied end to its free end.
    swap = values[inner] <= level
    inner, outer = np.where(swap, outer, inner), np.where(swap, inner, outer)
    # Edges whose free end lies exactly at the level (unknown space, p = 0.5) share that end.
    keys = np.where(values[outer] == level, 3 * values.size + outer, unique_edges)
    _, first, vertex_of_edge = np.unique(keys, return_index=True, return_inverse=True)
    inner, outer = inner[first], outer[first]
    t = (level - values[inner]) / (values[outer] - values[inner])
    low = np.column_stack(np.unravel_index(inner, probability.shape))
    high = np.column_stack(np.unravel_index(outer, probability.shape))
    vertices = low + t[:, None] * (high - low)
    faces = vertex_of_edge[faces]
    # Faces two of whose corners met in one point have no area.
    whole = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    return origin + (vertices + 0.5) * resolution, faces[whole]


def _crossed_cubes(inside: np.ndarray) -> np.ndarray:
    """(C,) int64 flat indices of the low corners of the cubes of eight voxel centres that have
    corners on both sides of the level."""
    nx, ny, nz = (n - 1 for n in inside.shape)
    # Grid-shaped, so that a cube's flat index is its low corner's; the last layers stay False.
    any_inside = np.zeros(inside.shape, dtype=bool)
    all_inside = np.zeros(inside.shape, dtype=bool)
    all_inside[:nx, :ny, :nz] = True
    for dx, dy, dz in CUBE_CORNERS:
        corner = inside[dx : nx + dx, dy : ny + dy, dz : nz + dz]
        any_inside[:nx, :ny, :nz] |= corner
        all_inside[:nx, :ny, :nz] &= corner
    return np.flatnonzero(any_inside & ~all_inside)


def joined_meshes(
    meshes: Iterable[tuple[np.ndarray, np.ndarray]], resolution: float
) -> tuple[np.ndarray, np.ndarray]:
    """One mesh of meshes that meet along shared faces (the blocks of ehm.grid.blocks):
    vertices closer than a ten-thousandth of `resolution` become one, so the surface stays
    closed across the seams. Returns vertices (V, 3) float64 and faces (F, 3) int64."""
    all_vertices, all_faces, count = [], [], 0
    for vertices, faces in meshes:
        all_vertices.append(vertices)
        all_faces.append(faces + count)
        count += len(vertices)
    if count == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    vertices, faces = np.concatenate(all_vertices), np.concatenate(all_faces)
    keys = np.round(vertices / (resolution * 1e-4)).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    faces = inverse.ravel()[faces]
    whole = (
        (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    )
    return vertices[first], faces[whole]
