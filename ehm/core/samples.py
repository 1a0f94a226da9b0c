"""Training data from scans: occupied samples around each hit and free samples along each ray
(the first step of Alg. 2; the paper assumes free space along beams, as Hilbert maps do)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig
from ehm.core.boxes import points_in_box, ray_box_intervals
from ehm.core.scan import Scan
from ehm.errors import InputError


@dataclass(frozen=True)
class TrainingSamples:
    """Labelled points for the classifier.

    points: (n, d) float64, metres, world frame. occupied: (n,) bool. at_surface: (n,) bool,
    True for the samples drawn around hits (both classes), False for free samples along rays.
    weight: (n,) float64, how many drawn samples each stands for in the loss (ones unless
    thinned, ehm.core.thinning; None gives ones).
    """

    points: np.ndarray
    occupied: np.ndarray
    at_surface: np.ndarray
    weight: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.weight is None:
            object.__setattr__(self, "weight", np.ones(len(self.points)))

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, rows: np.ndarray) -> TrainingSamples:
        """The samples at `rows` (boolean mask or indices)."""
        rows = np.asarray(rows)
        if rows.dtype == bool:
            rows = np.flatnonzero(rows)
        # np.take gathers rows of a 2D array several times faster than fancy indexing.
        return TrainingSamples(
            *(
                np.take(values, rows, axis=0)
                for values in (self.points, self.occupied, self.at_surface, self.weight)
            )
        )

    def __add__(self, other: TrainingSamples) -> TrainingSamples:
        """This set's samples followed by `other`'s."""
        return TrainingSamples.concatenate([self, other])

    @staticmethod
    def concatenate(parts: list[TrainingSamples]) -> TrainingSamples:
        return TrainingSamples(
            np.concatenate([p.points for p in parts]),
            np.concatenate([p.occupied for p in parts]),
            np.concatenate([p.at_surface for p in parts]),
            np.concatenate([p.weight for p in parts]),
        )


def training_samples(scan: Scan, config: MapConfig, rng: np.random.Generator) -> TrainingSamples:
    """Occupied and free samples along every ray of `scan`.

    Rays shorter than `min_range` are left out; rays longer than `max_range` (if set) end there
    without a hit. Around each hit: the hit and one point up to `occupied_depth` behind it are
    occupied; one point in the band from `surface_margin` / 4 to `surface_margin` in front of
    it is free. Along each ray, free points are drawn uniformly, `free_spacing` apart on
    average (at most `max_free_samples` of them), up to `surface_margin` before the hit, or
    over the whole length of a ray without return. With `learn_box`, only samples inside
    it are kept, free ones drawn along the part of each ray inside it alone.
    """
    offsets = scan.points_world - scan.origin
    lengths = np.linalg.norm(offsets, axis=1)
    usable = (lengths > 0) & (lengths >= config.min_range)
    offsets, lengths, hits = offsets[usable], lengths[usable], scan.hit_mask[usable]
    ends = scan.points_world[usable]
    if config.max_range > 0:
        hits = hits & (lengths <= config.max_range)
        scale = np.minimum(config.max_range / lengths, 1.0)
        offsets, lengths = offsets * scale[:, None], lengths * scale
        ends = scan.origin + offsets
    directions = offsets / lengths[:, None]
    margin = config.surface_margin

    hit_points = ends[hits]
    hit_dirs = directions[hits]
    behind_depth = config.occupied_depth * rng.random(len(hit_points))
    behind = hit_points + hit_dirs * behind_depth[:, None]
    front_depth = np.minimum(margin * (0.25 + 0.75 * rng.random(len(hit_points))), lengths[hits])
    in_front = hit_points - hit_dirs * front_depth[:, None]

    free_length = np.where(hits, np.maximum(lengths - margin, 0.0), lengths)
    # The free part of each ray that is learned: all of it, or the part inside learn_box,
    # sampled as densely as the whole ray (max_free_samples spreads a long ray's samples).
    spacing = np.maximum(config.free_spacing, free_length / config.max_free_samples)
    free_start, free_end = np.zeros(len(lengths)), free_length
    if config.learn_box:
        box = _learn_box(config, scan.dim)
        free_start, free_end = ray_box_intervals(scan.origin, directions, free_length, box)
    free_span = np.maximum(free_end - free_start, 0.0)
    counts = np.floor(free_span / spacing + rng.random(len(lengths))).astype(np.int64)
    counts = np.minimum(counts, config.max_free_samples)
    ray_of_sample = np.repeat(np.arange(len(counts)), counts)
    depth = free_start[ray_of_sample] + free_span[ray_of_sample] * rng.random(len(ray_of_sample))
    along = scan.origin + directions[ray_of_sample] * depth[:, None]

    points = np.concatenate([hit_points, behind, in_front, along])
    n_occupied = 2 * len(hit_points)
    occupied = np.zeros(len(points), dtype=bool)
    occupied[:n_occupied] = True
    at_surface = np.zeros(len(points), dtype=bool)
    at_surface[: n_occupied + len(in_front)] = True
    samples = TrainingSamples(points, occupied, at_surface)
    if config.learn_box:  # the samples around hits outside the box
        return samples.subset(points_in_box(points, box))
    return samples


def _learn_box(config: MapConfig, dim: int) -> np.ndarray:
    """config.learn_box as a (2, dim) array, metres; InputError for a box of another dim."""
    box = np.asarray(config.learn_box, dtype=np.float64).reshape(2, -1)
    if box.shape[1] != dim:
        raise InputError(f"MapConfig.learn_box is a {box.shape[1]}D box, the scan is {dim}D")
    return box


def samples_of_scans(
    scans: list[Scan], config: MapConfig, rng: np.random.Generator
) -> TrainingSamples:
    """The training samples of several scans, one after the other (single-batch mode)."""
    return TrainingSamples.concatenate([training_samples(s, config, rng) for s in scans])
