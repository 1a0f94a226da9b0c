"""Range scans and the occupied / free training samples drawn along their rays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig


@dataclass(frozen=True)
class TrainingSamples:
    """Labelled points for the classifier.

    points: (n, d) float64, metres, world frame. occupied: (n,) bool. at_surface: (n,) bool,
    True for the samples drawn around hits (both classes), False for free samples along rays.
    """

    points: np.ndarray
    occupied: np.ndarray
    at_surface: np.ndarray

    def __len__(self) -> int:
        return len(self.points)

    @staticmethod
    def concatenate(parts: list[TrainingSamples]) -> TrainingSamples:
        return TrainingSamples(
            np.concatenate([p.points for p in parts]),
            np.concatenate([p.occupied for p in parts]),
            np.concatenate([p.at_surface for p in parts]),
        )


class Scan:
    """One range scan: ray end points, the sensor origin and which rays returned.

    points_world: (N, d) float, metres, world frame, d = 2 or 3; for a ray without return the
        point is where the ray ends (for example at maximum range).
    origin: (d,) float, metres, world frame: the sensor centre all rays start from.
    hit_mask: (N,) bool, True where the ray hit a surface; None means every ray did.

    Points with NaN or infinite coordinates are dropped; `n_dropped` counts them.
    """

    def __init__(
        self,
        points_world: np.ndarray,
        origin: np.ndarray | None,
        hit_mask: np.ndarray | None = None,
    ) -> None:
        points = np.asarray(points_world, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] not in (2, 3):
            raise ValueError(
                f"scan points must have shape (N, 2) or (N, 3), got {tuple(points.shape)}"
            )
        if origin is None:
            raise ValueError("scan origin is missing: give the sensor position in world frame")
        origin = np.asarray(origin, dtype=np.float64)
        if origin.shape != (points.shape[1],):
            raise ValueError(
                f"scan origin has shape {tuple(origin.shape)}, points are {points.shape[1]}D"
            )
        if not np.all(np.isfinite(origin)):
            raise ValueError(f"scan origin is not finite: {origin.tolist()}")
        if hit_mask is None:
            hits = np.ones(len(points), dtype=bool)
        else:
            hits = np.asarray(hit_mask)
            if hits.shape != (len(points),):
                raise ValueError(
                    f"hit_mask has shape {tuple(hits.shape)}, expected ({len(points)},)"
                )
            if hits.dtype != bool:
                raise ValueError(f"hit_mask must be boolean, got dtype {hits.dtype}")
        finite = np.all(np.isfinite(points), axis=1)
        self.n_dropped = int(len(points) - finite.sum())
        self.points_world = points[finite]
        self.hit_mask = hits[finite]
        self.origin = origin
        if len(self.points_world) == 0:
            raise ValueError(
                f"scan is empty: no finite points ({self.n_dropped} non-finite dropped)"
            )

    @property
    def dim(self) -> int:
        return self.points_world.shape[1]

    def __len__(self) -> int:
        return len(self.points_world)

    def __repr__(self) -> str:
        return (
            f"Scan({len(self)} rays, {int(self.hit_mask.sum())} hits, {self.dim}D, "
            f"origin={np.round(self.origin, 3).tolist()}, dropped={self.n_dropped})"
        )

    def subset(self, rays: np.ndarray) -> Scan:
        """The scan restricted to some rays (boolean mask or indices)."""
        return Scan(self.points_world[rays], self.origin, self.hit_mask[rays])

    def training_samples(self, config: MapConfig, rng: np.random.Generator) -> TrainingSamples:
        """Occupied and free samples along every ray.

        Around each hit: the hit and one point up to `occupied_depth` behind it are occupied;
        one point in the band from `surface_margin` / 4 to `surface_margin` in front of it is
        free. Along each ray, free points are drawn uniformly, `free_spacing` apart on average,
        up to `surface_margin` before the hit, or over the whole length of a ray without return.
        """
        offsets = self.points_world - self.origin
        lengths = np.linalg.norm(offsets, axis=1)
        usable = lengths > 0
        offsets, lengths, hits = offsets[usable], lengths[usable], self.hit_mask[usable]
        directions = offsets / lengths[:, None]
        margin = config.surface_margin

        hit_points = self.points_world[usable][hits]
        hit_dirs = directions[hits]
        behind_depth = config.occupied_depth * rng.random(len(hit_points))
        behind = hit_points + hit_dirs * behind_depth[:, None]
        front_depth = np.minimum(
            margin * (0.25 + 0.75 * rng.random(len(hit_points))), lengths[hits]
        )
        in_front = hit_points - hit_dirs * front_depth[:, None]

        free_length = np.where(hits, np.maximum(lengths - margin, 0.0), lengths)
        expected = free_length / config.free_spacing
        counts = np.floor(expected + rng.random(len(expected))).astype(np.int64)
        ray_of_sample = np.repeat(np.arange(len(counts)), counts)
        depth = free_length[ray_of_sample] * rng.random(len(ray_of_sample))
        along = self.origin + directions[ray_of_sample] * depth[:, None]

        points = np.concatenate([hit_points, behind, in_front, along])
        n_occupied = 2 * len(hit_points)
        occupied = np.zeros(len(points), dtype=bool)
        occupied[:n_occupied] = True
        at_surface = np.zeros(len(points), dtype=bool)
        at_surface[: n_occupied + len(in_front)] = True
        return TrainingSamples(points, occupied, at_surface)
