"""Training data from scans: occupied samples around each hit and free samples along each ray
(the first step of Alg. 2; the paper assumes free space along beams, as Hilbert maps do)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ehm.config import MapConfig
from ehm.core.observations.planes import HitPlanes, hit_planes
from ehm.core.observations.range_noise import range_noise
from ehm.core.sensor.boxes import points_in_box, ray_box_intervals
from ehm.core.sensor.ray_spacing import angular_spacing
from ehm.core.sensor.scan import Scan
from ehm.errors import InputError


@dataclass(frozen=True)
class TrainingSamples:
    """Labelled points for the classifier.

    points: (n, d) float64, metres, world frame. occupied: (n,) bool. at_surface: (n,) bool,
    True for the samples drawn around hits (both classes) and the free samples along rays
    within MapConfig.fine_free_band of their hit, False for the other free samples along rays.
    weight: (n,) float64, how many drawn samples each stands for in the loss (None gives
    ones). scatter: (n, d, d) float64, m^2, the scatter of those samples about the point, for
    a point that is their mean (ehm.core.observations.evidence), or None: none (zero) for
    every sample. behind: (n,) bool, True for the occupied samples drawn behind hits (None
    gives none).
    """

    points: np.ndarray
    occupied: np.ndarray
    at_surface: np.ndarray
    weight: np.ndarray = None  # type: ignore[assignment]
    scatter: np.ndarray | None = None
    behind: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.weight is None:
            object.__setattr__(self, "weight", np.ones(len(self.points)))
        if self.behind is None:
            object.__setattr__(self, "behind", np.zeros(len(self.points), dtype=bool))

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
                None if values is None else np.take(values, rows, axis=0)
                for values in (
                    self.points,
                    self.occupied,
                    self.at_surface,
                    self.weight,
                    self.scatter,
                    self.behind,
                )
            )
        )

    def without_scatter(self) -> TrainingSamples:
        """The same samples with no scatter (learning needs none, clustering does)."""
        return TrainingSamples(
            self.points, self.occupied, self.at_surface, self.weight, None, self.behind
        )

    def __add__(self, other: TrainingSamples) -> TrainingSamples:
        """This set's samples followed by `other`'s."""
        return TrainingSamples.concatenate([self, other])

    @staticmethod
    def concatenate(parts: list[TrainingSamples]) -> TrainingSamples:
        """The samples of `parts` one after the other; a lone part with samples is returned
        as it is (a sweep's scatter is 19 MB)."""
        filled = [part for part in parts if len(part)]
        if len(filled) == 1:
            return filled[0]
        return TrainingSamples(
            np.concatenate([p.points for p in parts]),
            np.concatenate([p.occupied for p in parts]),
            np.concatenate([p.at_surface for p in parts]),
            np.concatenate([p.weight for p in parts]),
            _scatter_of(parts),
            np.concatenate([p.behind for p in parts]),
        )


def _scatter_of(parts: list[TrainingSamples]) -> np.ndarray | None:
    """The scatter of `parts` one after the other: None when none has any, else zeros for the
    parts without."""
    if all(p.scatter is None for p in parts):
        return None
    d = parts[0].points.shape[1]
    return np.concatenate(
        [np.zeros((len(p), d, d)) if p.scatter is None else p.scatter for p in parts]
    )


@dataclass(frozen=True)
class ScanRays:
    """The rays of scans that are learned, one row each (metres, world frame).

    origins: (n, d) each ray's start. directions: (n, d) unit vectors. lengths: (n,) distance
    to each ray's end (its hit, or where it stops without one). hits: (n,) bool.
    free_start, free_end: (n,) the part of each ray that gives free samples (start > end where
    it gives none). spacing: (n,) distance between its free samples. ray_spacing: (n,)
    radians, how far apart the rays of its scan are (ehm.core.sensor.ray_spacing). plane_side:
    the side of the cells whose hits `hit_normals` fits planes to (`cluster_radius`).
    """

    origins: np.ndarray
    directions: np.ndarray
    lengths: np.ndarray
    hits: np.ndarray
    free_start: np.ndarray
    free_end: np.ndarray
    spacing: np.ndarray
    ray_spacing: np.ndarray
    plane_side: float

    def __len__(self) -> int:
        return len(self.lengths)

    def subset(self, rows: np.ndarray) -> ScanRays:
        """The rays at `rows` (int64 indices), their planes still to be fitted."""
        per_ray = ("origins", "directions", "lengths", "hits", "free_start", "free_end")
        taken = {name: getattr(self, name)[rows] for name in per_ray}
        return ScanRays(
            **taken,
            spacing=self.spacing[rows],
            ray_spacing=self.ray_spacing[rows],
            plane_side=self.plane_side,
        )

    @cached_property
    def ends(self) -> np.ndarray:
        """(n, d) where each ray ends, metres: its hit, or where it stops without one; found
        once."""
        return self.origins + self.directions * self.lengths[:, None]

    @cached_property
    def hit_planes(self) -> HitPlanes:
        """The planes of the rays' hits, one row per ray (ehm.core.observations.planes.
        hit_planes, cells of `plane_side`), NaN for rays without a hit; found once."""
        n, d = self.directions.shape
        hits = self.hits
        if hits.all():  # a depth frame's rays: no rows to pick
            return hit_planes(self.ends, self.plane_side)
        planes = HitPlanes(np.full((n, d), np.nan), np.full(n, np.nan), np.full((n, d), np.nan))
        if hits.any():
            of_hits = hit_planes(self.ends[hits], self.plane_side)
            planes.normals[hits] = of_hits.normals
            planes.spreads[hits] = of_hits.spreads
            planes.axes[hits] = of_hits.axes
        return planes

    @property
    def hit_normals(self) -> np.ndarray:
        """(n, d) the unit normal of the plane the rays' hits lie on around each ray's hit
        (`hit_planes`), NaN for rays without a hit and hits on no plane."""
        return self.hit_planes.normals

    @cached_property
    def hit_noise(self) -> np.ndarray:
        """(n,) metres, the batch's range noise at each hit's range
        (ehm.core.observations.range_noise), 0 for rays without a hit; found once."""
        hits = self.hits
        planes = self.hit_planes
        if hits.all():
            return range_noise(self.lengths, self.directions, planes.spreads, planes.axes)
        noise = np.zeros(len(self))
        noise[hits] = range_noise(
            self.lengths[hits], self.directions[hits], planes.spreads[hits], planes.axes[hits]
        )
        return noise


def scan_rays(scans: list[Scan], config: MapConfig) -> ScanRays:
    """The learned rays of `scans`, in order.

    Rays shorter than `min_range` are left out; rays longer than `max_range` (if set) end there
    without a hit. Free samples are drawn up to `surface_margin` before a hit, or over the whole
    length of a ray without return, `free_spacing` apart (sparser on rays so long that they
    would give more than `max_free_samples`); with `learn_box`, only along the part of each ray
    inside it, as densely as along the whole ray.
    """
    # The batch's scans as one set of rays, each with its scan's origin: a 2D batch holds
    # hundreds of scans of a few hundred rays each.
    points = np.concatenate([scan.points_world for scan in scans])
    hits = np.concatenate([scan.hit_mask for scan in scans])
    counts = [len(scan) for scan in scans]
    origins = np.repeat(np.stack([scan.origin for scan in scans]), counts, axis=0)
    scan_of = np.repeat(np.arange(len(scans)), counts)
    offsets = points - origins
    lengths = np.linalg.norm(offsets, axis=1)
    usable = (lengths > 0) & (lengths >= config.min_range)
    if not usable.all():
        offsets, lengths, hits, origins, scan_of = (
            a[usable] for a in (offsets, lengths, hits, origins, scan_of)
        )
    if config.max_range > 0:
        hits = hits & (lengths <= config.max_range)
        scale = np.minimum(config.max_range / lengths, 1.0)
        offsets, lengths = offsets * scale[:, None], lengths * scale
    directions = offsets / lengths[:, None]
    free_length = np.where(hits, np.maximum(lengths - config.surface_margin, 0.0), lengths)
    spacing = np.maximum(config.free_spacing, free_length / config.max_free_samples)
    free_start, free_end = np.zeros(len(lengths)), free_length
    if config.learn_box:
        box = learn_box(config, points.shape[1])
        free_start, free_end = ray_box_intervals(origins, directions, free_length, box)
    return ScanRays(
        origins,
        directions,
        lengths,
        hits,
        free_start,
        free_end,
        spacing,
        angular_spacing(directions, scan_of),
        plane_side=config.cluster_radius,
    )


def ray_randoms(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) uniforms in [0, 1) that place each ray's samples: the depth of its sample
    behind the hit, of its sample in front, and the offset of its free samples."""
    return rng.random((n, 3))


# A hit's free sample lies at least this many surface margins in front of it.
FRONT_NEAREST = 0.25
# Least cosine between a ray and the normal of the plane of its hit that stretches the ray's
# free sample in front (`front_stretches`): at most 1 / FRONT_COS_FLOOR times as far along the
# ray. With 0.5 the hillside's near precision was 0.394 (seed 0; 0.403 without the stretch).
FRONT_COS_FLOOR = 0.3


def front_depth(margin: float, reach: float, u: float | np.ndarray) -> float | np.ndarray:
    """Distance in front of its hit of a hit's free sample, metres: from FRONT_NEAREST to
    `reach` times `margin` (`surface_margin`, metres; `reach`: MapConfig.front_reach), placed
    by u (uniform in [0, 1), scalar or array alike) raised to the power `reach`: uniform with
    reach 1, denser near the hit beyond (two in three within one margin with reach 2)."""
    return margin * (FRONT_NEAREST + (reach - FRONT_NEAREST) * u**reach)


def front_stretches(rays: ScanRays, config: MapConfig) -> np.ndarray:
    """(n,) how many times as far along each ray its hit's free sample lies: 1 / cos of the
    angle between the ray and the normal of the plane its batch's hits lie on around its hit
    (ScanRays.hit_normals), the cosine floored at FRONT_COS_FLOOR, so that the sample lies as
    far off the plane as on a ray along its normal. A ray at a grazing angle runs that close
    to the plane over a longer stretch, and a sample drawn only within one margin of its hit
    would lie a fraction of a margin off the surface. 1 for rays without a hit on a plane, and
    for every ray without `front_stretch`."""
    stretch = np.ones(len(rays))
    if not config.front_stretch:
        return stretch
    cosine = np.abs(np.einsum("nd,nd->n", rays.hit_normals, rays.directions))
    planar = ~np.isnan(cosine)
    stretch[planar] = 1.0 / np.maximum(cosine[planar], FRONT_COS_FLOOR)
    return stretch


def front_clearances(rays: ScanRays, config: MapConfig) -> np.ndarray:
    """(n,) metres each hit's free sample lies farther in front of it: `noise_clearance` times
    the batch's range noise at its range (ScanRays.hit_noise), so that it lies in front of the
    band the noise spreads a surface's hits over, where the other hits read it occupied. Zeros
    with `noise_clearance` 0."""
    if config.noise_clearance == 0:
        return np.zeros(len(rays))
    return config.noise_clearance * rays.hit_noise


# Free samples along a ray farther than FAR_REACH free cluster radii from its hit, and all along
# a ray without one, lie MapConfig.free_thinning times as far apart, each standing for as
# many: where rays spread apart, each of them makes a cell of its own.
FAR_REACH = 2.0


def _dense_free_start(rays: ScanRays, config: MapConfig) -> np.ndarray:
    """(n,) metres: where each ray's free samples lie `spacing` apart, up to its free end:
    FAR_REACH free cluster radii before its hit, within its free part; at its free end (none
    dense) for a ray without a hit; at its free start (all dense) with `free_thinning` 1."""
    if config.free_thinning == 1:
        return rays.free_start
    start = np.where(rays.hits, rays.lengths - FAR_REACH * config.free_cluster_radius, np.inf)
    return np.clip(start, rays.free_start, np.maximum(rays.free_end, rays.free_start))


def free_sample_counts(
    rays: ScanRays, randoms: np.ndarray, config: MapConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(far, dense, dense_start): the free samples of each ray, far (n,) int64 of them one in
    each `free_thinning` spacings from its free start to its dense start (n,) metres
    (`_dense_free_start`), then dense (n,) int64 one in each `spacing` to its free end, each
    stretch from the offset randoms[:, 2] on; `max_free_samples` at most."""
    dense_start = _dense_free_start(rays, config)
    offset = randoms[:, 2]
    far_spacing = config.free_thinning * rays.spacing
    far = _stratified(dense_start - rays.free_start, far_spacing, offset)
    dense = _stratified(rays.free_end - dense_start, rays.spacing, offset)
    far = np.minimum(far, config.max_free_samples)
    return far, np.minimum(dense, config.max_free_samples - far), dense_start


def _stratified(span: np.ndarray, spacing: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """(n,) int64 samples in stretches of `span` metres, one in each `spacing` from `offset`
    (in [0, 1), of a spacing) on: span / spacing in expectation."""
    counts = np.floor(span / spacing + 1.0 - offset).astype(np.int64)
    return np.where(span > 0.0, counts, 0)


def training_samples(scan: Scan, config: MapConfig, rng: np.random.Generator) -> TrainingSamples:
    """Occupied and free samples along every ray of `scan` (see `scan_rays` for which rays
    and which part of each).

    Around each hit: the hit and one point up to `occupied_depth` behind it are occupied; one
    point from `surface_margin` / 4 to `front_reach` times `surface_margin` in front of it
    (`front_depth`), that many times its ray's stretch (`front_stretches`) along the ray, is
    free.
    Along each ray, free points are stratified: one in each `spacing` of its free part, from a
    random offset, where it lies within FAR_REACH free cluster radii of the ray's hit; one in
    each `free_thinning` spacings, of that weight, farther and along rays without a hit; those
    within `fine_free_band` free cluster radii before the hit are at_surface. With
    `learn_box`, the samples around hits outside it are left out.
    """
    rays = scan_rays([scan], config)
    return samples_of_rays(rays, ray_randoms(len(rays), rng), config)


def samples_of_rays(rays: ScanRays, randoms: np.ndarray, config: MapConfig) -> TrainingSamples:
    """The samples of `rays` placed by `randoms` (see ray_randoms), as `training_samples`
    describes them."""
    hits = rays.hits
    hit_points = rays.ends[hits]
    hit_dirs = rays.directions[hits]
    behind = hit_points + hit_dirs * (config.occupied_depth * randoms[hits, 0])[:, None]
    stretch = front_stretches(rays, config)[hits]
    clearance = front_clearances(rays, config)[hits]
    in_front_depth = np.minimum(
        stretch * front_depth(config.surface_margin, config.front_reach, randoms[hits, 1])
        + clearance,
        rays.lengths[hits],
    )
    in_front = hit_points - hit_dirs * in_front_depth[:, None]
    far, dense, dense_start = free_sample_counts(rays, randoms, config)
    runs = (
        (far, rays.free_start, config.free_thinning * rays.spacing),
        (dense, dense_start, rays.spacing),
    )
    along, near_hit = [], []
    band = config.fine_free_band * config.free_cluster_radius
    for counts, start, spacing in runs:
        ray_of_sample = np.repeat(np.arange(len(counts)), counts)
        rank = np.arange(len(ray_of_sample)) - np.repeat(np.cumsum(counts) - counts, counts)
        depth = start[ray_of_sample] + (rank + randoms[ray_of_sample, 2]) * spacing[ray_of_sample]
        along.append(rays.origins[ray_of_sample] + rays.directions[ray_of_sample] * depth[:, None])
        near_hit.append(rays.hits[ray_of_sample] & (rays.lengths[ray_of_sample] - depth < band))
    # Each hit's three samples together, then the free samples of every ray.
    surface = np.stack([hit_points, behind, in_front], axis=1).reshape(-1, rays.origins.shape[1])
    points = np.concatenate([surface, *along])
    n_surface = len(surface)
    occupied = np.zeros(len(points), dtype=bool)
    occupied[:n_surface] = np.tile([True, True, False], len(hit_points))
    behind_hit = np.zeros(len(points), dtype=bool)
    behind_hit[:n_surface] = np.tile([False, True, False], len(hit_points))
    around_hit = np.zeros(len(points), dtype=bool)
    around_hit[:n_surface] = True
    at_surface = around_hit.copy()
    at_surface[n_surface:] = np.concatenate(near_hit)  # within fine_free_band of their hit
    weight = np.ones(len(points))
    weight[n_surface : n_surface + len(along[0])] = config.free_thinning
    samples = TrainingSamples(points, occupied, at_surface, weight, None, behind_hit)
    if config.learn_box:  # the samples around hits outside the box
        box = learn_box(config, rays.origins.shape[1])
        return samples.subset(~around_hit | points_in_box(points, box))
    return samples


def learn_box(config: MapConfig, dim: int) -> np.ndarray:
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
