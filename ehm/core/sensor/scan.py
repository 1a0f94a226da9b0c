"""Range scans: ray end points in world frame, the sensor origin and which rays returned."""

from __future__ import annotations

import numpy as np

from ehm.errors import InputError


class Scan:
    """One range scan: ray end points, the sensor origin and which rays returned.

    points_world: (N, d) float, metres, world frame, d = 2 or 3; for a ray without return the
        point is where the ray ends (for example at maximum range).
    origin: (d,) float, metres, world frame: the sensor centre all rays start from.
    hit_mask: (N,) bool, True where the ray hit a surface; None means every ray did.
    time: seconds, when the scan was taken (any fixed epoch: Unix time, the log's start); None
        when unknown. Maps that forget what they have not seen for a while need it
        (MapConfig.forget_after).

    Points with NaN or infinite coordinates are dropped; `n_dropped` counts them.
    """

    def __init__(
        self,
        points_world: np.ndarray,
        origin: np.ndarray | None,
        hit_mask: np.ndarray | None = None,
        time: float | None = None,
    ) -> None:
        points = np.asarray(points_world, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] not in (2, 3):
            raise InputError(
                f"scan points must have shape (N, 2) or (N, 3), got {tuple(points.shape)}"
            )
        if origin is None:
            raise InputError("scan origin is missing: give the sensor position in world frame")
        origin = np.asarray(origin, dtype=np.float64)
        if origin.shape != (points.shape[1],):
            raise InputError(
                f"scan origin has shape {tuple(origin.shape)}, points are {points.shape[1]}D"
            )
        if not np.all(np.isfinite(origin)):
            raise InputError(f"scan origin is not finite: {origin.tolist()}")
        if hit_mask is None:
            hits = np.ones(len(points), dtype=bool)
        else:
            hits = np.asarray(hit_mask)
            if hits.shape != (len(points),):
                raise InputError(
                    f"hit_mask has shape {tuple(hits.shape)}, expected ({len(points)},)"
                )
            if hits.dtype != bool:
                raise InputError(f"hit_mask must be boolean, got dtype {hits.dtype}")
        self.time = None if time is None else _seconds(time)
        finite = np.all(np.isfinite(points), axis=1)
        self.n_dropped = int(len(points) - finite.sum())
        self.points_world = points[finite]
        self.hit_mask = hits[finite]
        self.origin = origin
        if len(self.points_world) == 0:
            raise InputError(
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
            f"origin={np.round(self.origin, 3).tolist()}, dropped={self.n_dropped}"
            + ("" if self.time is None else f", time={self.time:.3f}")
            + ")"
        )

    def subset(self, rays: np.ndarray) -> Scan:
        """The scan restricted to some rays (boolean mask or indices)."""
        return Scan(self.points_world[rays], self.origin, self.hit_mask[rays], self.time)


def _seconds(time: object) -> float:
    """A scan's time stamp as float seconds; InputError for anything but a finite number."""
    try:
        seconds = float(time)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        seconds = float("nan")
    if not np.isfinite(seconds):
        raise InputError(f"scan time must be a finite number of seconds, got {time!r}")
    return seconds
