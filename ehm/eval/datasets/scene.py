"""Analytic scenes with exact occupancy: solid boxes and balls in 2D or 3D, and ray casting."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Scene:
    """Solids in world frame, metres.

    box_min, box_max: (B, d) opposite corners of axis-aligned solid boxes.
    ball_centres: (S, d); ball_radii: (S,).
    """

    box_min: np.ndarray
    box_max: np.ndarray
    ball_centres: np.ndarray
    ball_radii: np.ndarray

    @property
    def dim(self) -> int:
        return self.box_min.shape[1]

    def occupied(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool: True where a point lies inside a solid. points: (n, d), metres."""
        points = np.asarray(points, dtype=np.float64)
        inside = np.zeros(len(points), dtype=bool)
        for lo, hi in zip(self.box_min, self.box_max, strict=True):
            inside |= np.all((points >= lo) & (points <= hi), axis=1)
        for centre, radius in zip(self.ball_centres, self.ball_radii, strict=True):
            inside |= np.sum((points - centre) ** 2, axis=1) <= radius**2
        return inside

    def surface_distance(self, points: np.ndarray) -> np.ndarray:
        """(n,) metres from each point (n, d) to the nearest solid surface. Outside the solids:
        the distance to the nearest solid. Inside: the depth below the surface of the solid
        the point lies deepest in (exact where solids do not overlap)."""
        points = np.asarray(points, dtype=np.float64)
        outside = np.full(len(points), np.inf)
        depth = np.zeros(len(points))
        for lo, hi in zip(self.box_min, self.box_max, strict=True):
            gap = np.maximum(np.maximum(lo - points, points - hi), 0.0)
            outside = np.minimum(outside, np.linalg.norm(gap, axis=1))
            inner = np.minimum(points - lo, hi - points).min(axis=1)
            depth = np.maximum(depth, inner)
        for centre, radius in zip(self.ball_centres, self.ball_radii, strict=True):
            signed = np.linalg.norm(points - centre, axis=1) - radius
            outside = np.minimum(outside, np.maximum(signed, 0.0))
            depth = np.maximum(depth, -signed)
        return np.where(depth > 0.0, depth, outside)

    def raycast(self, origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(n,) distance, metres, from origin along unit directions (n, d) to the first solid
        surface; inf where a ray hits nothing."""
        directions = np.asarray(directions, dtype=np.float64)
        nearest = np.full(len(directions), np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            inverse = 1.0 / directions
            for lo, hi in zip(self.box_min, self.box_max, strict=True):
                t0 = (lo - origin) * inverse
                t1 = (hi - origin) * inverse
                t_near = np.nanmax(np.minimum(t0, t1), axis=1)
                t_far = np.nanmin(np.maximum(t0, t1), axis=1)
                hit = (t_near <= t_far) & (t_far > 0)
                nearest = np.where(hit, np.minimum(nearest, np.maximum(t_near, 0.0)), nearest)
        for centre, radius in zip(self.ball_centres, self.ball_radii, strict=True):
            offset = origin - centre
            b = directions @ offset
            c = offset @ offset - radius**2
            disc = b * b - c
            root = np.sqrt(np.maximum(disc, 0.0))
            t = np.where(-b - root > 0, -b - root, -b + root)
            hit = (disc >= 0) & (t > 0)
            nearest = np.where(hit, np.minimum(nearest, t), nearest)
        return nearest


def room_shell(interior_min: np.ndarray, interior_max: np.ndarray, thickness: float):
    """Boxes (2d of them) forming the walls around an axis-aligned interior, as (min, max)."""
    interior_min = np.asarray(interior_min, dtype=np.float64)
    interior_max = np.asarray(interior_max, dtype=np.float64)
    outer_min, outer_max = interior_min - thickness, interior_max + thickness
    lows, highs = [], []
    for axis in range(len(interior_min)):
        for side in (0, 1):
            lo, hi = outer_min.copy(), outer_max.copy()
            if side == 0:
                hi[axis] = interior_min[axis]
            else:
                lo[axis] = interior_max[axis]
            lows.append(lo)
            highs.append(hi)
    return np.array(lows), np.array(highs)
