"""The held-out-rays protocol (the paper's sparsity test, Sec. 4) and test points for scoring
against a simulated scene's exact occupancy."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ehm.core.sensor.scan import Scan
from ehm.errors import InputError


@dataclass(frozen=True)
class HeldOutSplit:
    """Training scans and labelled test points: points (n, d), metres; occupied (n,) bool;
    train_rays: per scan, (N,) bool, True for the rays in the training scan."""

    train: list[Scan]
    points: np.ndarray
    occupied: np.ndarray
    train_rays: list[np.ndarray]


def held_out_rays(
    scans: list[Scan], train_fraction: float, resolution: float, seed: int
) -> HeldOutSplit:
    """In each scan a random `train_fraction` of the rays trains the map, the rest are held out.

    Each held-out hit is an occupied test point; each held-out ray gives one free test point at
    a distance uniform in [0, r - 2 resolution] from the origin (none when that is negative).
    A ray is never in both sets.
    """
    if not 0.0 < train_fraction < 1.0:
        raise InputError(f"train fraction must be in (0, 1), got {train_fraction}")
    rng = np.random.default_rng(seed)
    train, points, occupied, train_rays = [], [], [], []
    for scan in scans:
        in_train = rng.random(len(scan)) < train_fraction
        train.append(scan.subset(in_train))
        train_rays.append(in_train)
        ends, hits = scan.points_world[~in_train], scan.hit_mask[~in_train]
        offsets = ends - scan.origin
        lengths = np.linalg.norm(offsets, axis=1)
        free_extent = lengths - 2.0 * resolution
        usable = free_extent > 0
        depth = free_extent[usable] * rng.random(int(usable.sum()))
        free = scan.origin + offsets[usable] / lengths[usable, None] * depth[:, None]
        points += [ends[hits], free]
        occupied += [np.ones(int(hits.sum()), bool), np.zeros(len(free), bool)]
    return HeldOutSplit(train, np.concatenate(points), np.concatenate(occupied), train_rays)


def observed_mask(scans: list[Scan], points: np.ndarray, tolerance: float) -> np.ndarray:
    """(n,) bool: points some ray has reached, within `tolerance` metres past its end.

    For each scan, the ray closest in direction to the point (as seen from the scan's origin)
    decides: the point is observed when it lies no farther than that ray's length + tolerance.
    """
    reached = np.zeros(len(points), dtype=bool)
    for scan in scans:
        offsets = scan.points_world - scan.origin
        lengths = np.linalg.norm(offsets, axis=1)
        usable = lengths > 0
        tree = cKDTree(offsets[usable] / lengths[usable, None])
        query = points - scan.origin
        distance = np.linalg.norm(query, axis=1)
        _, ray = tree.query(query / np.maximum(distance, 1e-12)[:, None])
        reached |= distance <= lengths[usable][ray] + tolerance
    return reached


def near_surface_points(
    scans: list[Scan], spread: float, per_hit: float, rng: np.random.Generator
) -> np.ndarray:
    """Points scattered around the hits, Gaussian with `spread` metres per axis: a test set
    near surfaces, to be labelled with a scene's exact occupancy. (round(per_hit * hits), d)."""
    hits = np.concatenate([s.points_world[s.hit_mask] for s in scans])
    chosen = rng.choice(len(hits), size=round(per_hit * len(hits)), replace=True)
    return hits[chosen] + rng.normal(0.0, spread, (len(chosen), hits.shape[1]))


def exact_test_points(
    scans: list[Scan],
    box_min: np.ndarray,
    box_max: np.ndarray,
    per_hit: float,
    n_uniform: int,
    tolerance: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Test points for scoring against a scene's exact occupancy, both kept only where observed
    (within `tolerance` metres past a ray's end): points 0.1 m (Gaussian, per axis) around the
    hits, `per_hit` of them per hit, and `n_uniform` uniform draws in the box from `box_min` to
    `box_max` (d,), metres. Returns (near, uniform), each (m, d)."""
    near = near_surface_points(scans, 0.1, per_hit, rng)
    uniform = rng.uniform(box_min, box_max, (n_uniform, len(box_min)))
    return (
        near[observed_mask(scans, near, tolerance)],
        uniform[observed_mask(scans, uniform, tolerance)],
    )
