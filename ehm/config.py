"""One validated configuration object: every tunable of a map, with its default and unit."""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from functools import cache
from typing import Any, Literal

from ehm.errors import InputError, SettingsError

FeatureSearch = Literal["support", "nearest"]
MergeRule = Literal["pooled", "average"]
QueryMode = Literal["batch", "exact"]
TrainSearch = Literal["group", "point"]
UpdateRule = Literal["sgd", "posterior"]
Profile = Literal["default", "realtime"]


# The map detail the defaults are set for, metres (MapConfig.for_resolution scales the settings
# that are lengths from it).
DEFAULT_RESOLUTION = 0.05
# The shortest length a setting may take, metres: below it, kernels of that spread
# overflow in double precision.
SMALLEST_LENGTH = 1e-6
# The real-time profile (MapConfig.for_resolution): settings over the default's, and how much
# wider its occupied clusters are. Its features are the nearest kernels: a sample's features
# then hold about a third as many kernels, which stochastic gradient descent pays for.
REALTIME = {"epochs": 1, "surface_pooling": 2, "free_thinning": 2, "features": "nearest"}
REALTIME_CLUSTER_SCALE = 1.5
# The sections of the settings, in the order settings files and `ehm info` give them.
SECTIONS = ("sampling", "clustering", "kernels", "search", "learning", "memory", "queries")


def setting(
    default: Any,
    section: str,
    *,
    unit: str = "",
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    length: bool = False,
) -> Any:
    """A MapConfig field: its default, its section (SECTIONS), its unit, the bounds its value
    must keep (open: the bound itself excluded) and whether it is a length that scales with
    the map's resolution (MapConfig.for_resolution)."""
    bounds = {"low": low, "high": high, "low_open": low_open, "high_open": high_open}
    return dataclasses.field(
        default=default, metadata={"section": section, "unit": unit, "length": length, **bounds}
    )


@dataclass(frozen=True)
class MapConfig:
    """Settings of an Efficient Hilbert Map.

    Distances are in metres. Defaults suit LiDAR and depth cameras at about 5 cm detail
    (DEFAULT_RESOLUTION); `MapConfig.for_resolution` gives the settings for another detail.
    The measurements behind the defaults chosen between alternatives are in the docs' page
    "Why these defaults" (docs/reference/defaults.md).
    """

    # Sampling: which rays are learned and the training samples drawn along them
    # (ehm.core.observations.samples).
    min_range: float = setting(0.0, "sampling", unit="m", low=0.0)
    """Rays shorter than this are left out, metres: returns from the robot itself."""
    max_range: float = setting(0.0, "sampling", unit="m")
    """Rays longer than this are cut here and learned as rays without return (free space up
    to max_range, no hit), as OctoMap's maxrange does, metres; 0 for no limit. A sensor's
    glitch far away then costs one ray, not a far cluster."""
    learn_box: tuple[float, ...] = setting((), "sampling", unit="m")
    """Learn only inside this box: its low corner then its high corner, metres, world frame
    (4 numbers in 2D, 6 in 3D); empty, everywhere. Samples outside it are left out and free
    samples are drawn only along the part of each ray inside it, as densely as along the
    whole ray, so a map of a box learns what a map of everything learns there. The tiles of
    a TiledMap are such maps."""
    max_free_samples: int = setting(1000, "sampling", low=1)
    """Most free samples drawn along one ray: a longer ray gets them sparser, so a scan's
    samples are bounded by its rays, never by how far one point lies (at the default
    free_spacing, 1000 samples reach 600 m)."""
    free_spacing: float = setting(0.6, "sampling", unit="m", low=0.0, low_open=True, length=True)
    """Mean distance between free samples along a ray, metres (density of free samples)."""
    free_thinning: int = setting(1, "sampling", low=1)
    """Free samples farther than two free cluster radii from their ray's hit, and along rays
    without one, lie this many times free_spacing apart, each standing for as many. 1: more
    builds outdoor scenes faster but loses thin posts that rays pass far from their hits."""
    surface_pooling: int = setting(1, "sampling", low=1)
    """The samples behind and in front of hits are gathered in cells this many times as wide
    as the hits' own (ehm.core.observations.evidence; a quarter of a cluster radius). 1: 2
    learns crowded hits (a depth camera's) faster, at the cost of slightly thicker surfaces."""
    fine_free_band: float = setting(0.0, "sampling", low=0.0)
    """Free samples along a ray that lie within this many free cluster radii before its hit
    are gathered and clustered as the samples around hits are (fine cells, cluster_radius),
    not as open space: fine free kernels then cover the space just in front of surfaces, which
    otherwise only coarse kernels straddling them reach. 0: none."""
    surface_margin: float = setting(0.05, "sampling", unit="m", low=0.0, low_open=True, length=True)
    """Margin in front of each hit, metres: free samples along the ray stop this far before
    it, and one free sample is drawn from a quarter of it to `front_reach` times it in front
    of it."""
    front_reach: float = setting(1.0, "sampling", low=1.0)
    """How far in front of its hit a hit's free sample may lie, in surface margins: uniform up
    to one margin with 1, denser near the hit beyond (ehm.core.observations.samples.
    front_depth). 1: farther thins surfaces faced head-on, but thin posts seen from afar fade."""
    front_stretch: bool = setting(True, "sampling")
    """Where a batch's hits around a hit lie on a plane, the hit's free sample lies as far off
    the plane as it would on a ray along the plane's normal: 1 / cos of the ray's angle to the
    normal as far along the ray (the cosine floored at 0.3;
    ehm.core.observations.samples.front_stretches). On: ground and walls seen at grazing
    angles read thinner, where rays otherwise leave them thick."""
    noise_clearance: float = setting(2.0, "sampling", low=0.0)
    """A hit's free sample lies this many standard deviations of the range noise farther in
    front of it, the noise read off the batch's own hits at the hit's range (their spread
    about the planes they lie on, ehm.core.observations.range_noise): in front of the band
    the noise spreads a surface's hits over, where the others read it occupied. Noisy depth
    reads hits occupied; surfaces read a little thicker. 0: within `surface_margin` of the
    hit, however noisy."""
    occupied_depth: float = setting(0.15, "sampling", unit="m", low=0.0, low_open=True, length=True)
    """One occupied sample is drawn up to this far behind each hit, metres: surfaces are taken
    to be solid this deep."""
    batch_rays: int = setting(20_000, "sampling", low=0)
    """Scans are gathered until they hold at least this many rays, then learned as one batch
    (one gathering of evidence, one clustering, one SGD run). A query, a grid or `flush()`
    learns the scans still waiting first, so every answer sees every scan given. Small scans
    (a 2D laser's few hundred rays) then share the fixed cost of an update and form their
    clusters together, faster and more accurately than one by one; scans of a LiDAR or a
    depth camera hold more rays and are learned as they come. 0 learns every scan as it
    comes."""

    # Clustering: quick-means (Alg. 1), merging into the map's clusters (Alg. 2) and
    # orientation clustering (Eq. 14-15).
    cluster_radius: float = setting(
        0.12, "clustering", unit="m", low=0.0, low_open=True, length=True
    )
    """Inner radius r_i of quick-means for occupied samples, metres."""
    outer_radius_factor: float = setting(1.5, "clustering", low=1.0)
    """Outer radius r_o as a multiple of the inner radius."""
    free_cluster_radius: float = setting(
        0.6, "clustering", unit="m", low=0.0, low_open=True, length=True
    )
    """Inner radius r_i of quick-means for free samples along rays, metres, when clustered
    apart; they form the coarse clusters. Samples around hits use `cluster_radius`."""
    hits_per_radius: float = setting(1.5, "clustering", low=0.0)
    """Fine clusters where hits lie far apart are wider: 2, 4 times `cluster_radius`, the
    least that spans this many ray footprints (the rays' angular spacing times the distance
    from the sensor; ehm.core.clustering.footprints). 0: every fine cluster of
    `cluster_radius`."""
    min_cluster_size: int = setting(4, "clustering", low=1)
    """Quick-means drops seeds with fewer samples than this within the outer radius."""
    min_hit_cluster_size: int = setting(2, "clustering", low=1)
    """The least weight of a cluster of hits and the samples behind them: 2, one hit and its
    sample behind. Evidence that forms no cluster waits for a later batch to bring more to its
    cell; with `min_cluster_size` (4) a thin thing that rays meet once each (a wire a LiDAR's
    rings cross) gets none, and the free space around it reads it free."""
    kmeans_iterations: int = setting(0, "clustering", low=0)
    """Lloyd iterations refining quick-means centres (0 = use quick-means as it is)."""
    cluster_free_apart: bool = setting(True, "clustering")
    """Cluster occupied and free samples separately (True) or together (False)."""
    cluster_behind_apart: bool = setting(False, "clustering")
    """With `cluster_free_apart`, the occupied samples behind hits are clustered apart from the
    hits, each needing half of `min_cluster_size`: a surface's kernels then lie on it, as
    thin as its hits, and the solid behind it has kernels of its own. Off: one cluster of
    both, centred behind the surface and as deep as `occupied_depth`, whose kernel reaches
    farther in front of it."""
    merge_coplanar: bool = setting(False, "clustering")
    """Orientation clustering (Eq. 14-15): after each update, planar clusters it touched merge
    with planar neighbours of the same scale and label whose normals and positions agree,
    until no more merge. Off: fewer clusters, but less accuracy near surfaces."""
    coplanar_angle: float = setting(
        10.0, "clustering", unit="degrees", low=0.0, low_open=True, high=90.0, high_open=True
    )
    """Largest angle between the normals of clusters that merge as co-planar, degrees."""
    coplanar_distance: float = setting(2.0, "clustering", low=0.0, low_open=True)
    """Largest anisotropic distance (Eq. 14) between clusters that merge as co-planar."""
    merge_rule: MergeRule = setting("pooled", "clustering")
    """'pooled': exact pooled mean and covariance weighted by sample counts; 'average': the
    paper's mean of means and mean of covariances (Alg. 2 lines 19-20)."""
    merge_threshold: float = setting(1.0, "clustering", low=0.0, low_open=True)
    """Anisotropic distance (Eq. 14) below which a new cluster merges into the map's."""

    # Kernels: the localized length-scale features (Eq. 8, 10-12) and kernel selection
    # (Sec. 3.2).
    features: FeatureSearch = setting("support", "kernels")
    """Which kernels make up a point's feature vector. 'support': every kernel that is not
    zero there, found in a spatial hash of the kernels' supports that is updated in time
    proportional to what changed (ehm.core.search.supports), so training, point queries and
    grids share one model. 'nearest': the paper's Alg. 3, the `neighbours` nearest fine and
    `coarse_neighbours` nearest coarse clusters, searched once per group of points (kd-trees
    or anchor layers); kernels beyond them are left out, so point queries differ from grids
    (Sec. 3.5), which sum every kernel; it learns faster (the real-time profile's)."""
    length_scale: float = setting(3.0, "kernels", low=0.0, low_open=True)
    """Kernel support in standard deviations of the cluster (r = 1 at this many sigmas), for
    the kernels of free clusters."""
    occupied_length_scale: float = setting(3.5, "kernels", low=0.0, low_open=True)
    """The same for the kernels of occupied clusters. Wider than free ones, they reach the hits
    that range noise puts in front of a surface."""
    min_std: float = setting(0.02, "kernels", unit="m", low=0.0, low_open=True, length=True)
    """Floor on each cluster's standard deviation along any axis, metres."""
    neighbours: int = setting(8, "kernels", low=1)
    """Fine clusters that enter each point's feature vector (k nearest fine centres), with
    features 'nearest'."""
    coarse_neighbours: int = setting(4, "kernels", low=0)
    """Coarse free-space clusters that enter each point's feature vector as well, with
    features 'nearest'. Coarse kernels overlap more than fine ones: more of them bring point
    queries closer to the grid's sum over every kernel (Sec. 3.5), at a query's cost."""
    planar_ratio: float = setting(0.1, "kernels", low=0.0, low_open=True, high=1.0, high_open=True)
    """A cluster is planar (a wall, a floor; a line segment in 2D) when its smallest covariance
    eigenvalue is at most this share of the next smallest."""
    planar_kernel: bool = setting(False, "kernels")
    """Planar clusters use the planar-surface kernel (Eq. 13, 1 within two standard deviations
    along each eigen-axis); the others, and all when False, the localized length-scale one.
    Off: it puts the occupied boundary centimetres in front of walls."""

    # Search: finding each point's clusters with features 'nearest' (Sec. 3.1, 3.4).
    anisotropic_search: bool = setting(False, "search")
    """Rank the clusters of a point by the radius their kernel gives it, |T_m (x - mu_m)|,
    rather than by the Euclidean distance between the point and their centres. Off: slower
    queries, no more accurate."""
    anisotropic_candidates: int = setting(3, "search", low=1)
    """Anisotropic search re-ranks this many times k nearest centres."""
    anchor_layers: int = setting(1, "search", low=1)
    """Layers of the cluster hierarchy (Fig. 6): 1 searches the clusters directly (kd-trees);
    each further layer groups the one below into anchors, searched top-down. 1: the same
    neighbours, found faster by the kd-tree."""
    anchor_radius_factor: float = setting(4.0, "search", low=1.0, low_open=True)
    """Inner quick-means radius of the first anchor layer, as a multiple of the clusters'
    radius (`cluster_radius` or `free_cluster_radius`); each further layer multiplies it
    again."""
    train_search: TrainSearch = setting("group", "search")
    """With features 'nearest': 'group', one neighbour search per quick-means group of
    training samples (Alg. 2); 'point', one per sample, as LLS-HM (Guizilini & Ramos 2016)
    does."""

    # Learning: the weights' update (Alg. 2).
    update_rule: UpdateRule = setting("sgd", "learning")
    """How each scan's samples update the weights: 'sgd', AdaGrad stochastic gradient descent on
    the regularised loss (Alg. 2); 'posterior', a Gaussian posterior per weight updated with the
    previous one as prior (ehm.core.weights.posterior). 'sgd': more accurate scan by scan and
    in one batch, and replayed samples would count twice in a posterior that already holds
    them."""
    learning_rate: float = setting(0.3, "learning", low=0.0, low_open=True)
    """AdaGrad step size of the stochastic gradient steps ('sgd')."""
    l2: float = setting(1e-3, "learning", low=0.0)
    """L2 regularisation of the weights (the R(w) of Eq. 2; 'sgd')."""
    prior_precision: float = setting(1.0, "learning", low=0.0, low_open=True)
    """Precision (1 / variance) of a new weight's Gaussian prior, centred on the weight it joins
    with (`initial_weight`; 0 for coarse clusters): the log-odds variance of never-observed
    space (occupancy std 0.21 at 1; ehm.core.weights.uncertainty), and under 'posterior' the
    prior the first update starts from."""
    initial_weight: float = setting(2.0, "learning", low=0.0)
    """Log-odds weight a new fine cluster joins with, then learned: + for clusters of hits,
    - for free ones around hits; coarse clusters (open space along rays) join at 0. A fine
    cluster few samples train (far, sparse hits; a wire a few rays met) stays near where its
    first steps leave it: from 0, the free kernels around read its hits free. 0: every new
    cluster at 0, no prior knowledge of its occupancy."""
    coarse_free_only: bool = setting(True, "learning")
    """Hold the weights of coarse clusters (open free space, from free samples along rays) at
    or below 0, so they only ever read space free. Unconstrained, SGD gives some of them
    positive weights near surfaces, where they offset the intercept; queries leave the
    intercept out, so such a kernel reads observed free space occupied up to its reach
    (about 1 m at 0.05 m) in front of surfaces. False: the paper's unconstrained weights."""
    balance_classes: bool = setting(False, "learning")
    """Weight occupied and free samples so each class carries half of the loss."""
    epochs: int = setting(2, "learning", low=1)
    """Passes over each scan's samples: epochs of stochastic gradient descent, or sweeps of
    coordinate descent ('posterior')."""
    seed: int = setting(0, "learning")
    """Seed of every random choice (sampling, quick-means order, SGD order)."""

    # Memory and forgetting: the evidence of past scans, and what fades.
    keep_evidence: bool = setting(True, "memory")
    """Keep the evidence of past scans, one weighted mean per cell and kind
    (ehm.core.observations.memory): it is replayed with later scans that reach its place, and what
    formed no cluster yet is clustered again with a later scan's evidence in its cell. False: each
    scan is learned from its own evidence alone, as Alg. 2 does."""
    replay_ratio: float = setting(1.0, "memory", low=0.0)
    """Weight of the past evidence replayed with each batch, per unit of the batch's own: from
    the cells around hits as much as the batch has there (times the ratio), the rest from the
    cells along rays, each cell in proportion to the weight it has seen."""
    replay_cap: float | None = setting(2.0, "memory", low=0.0, low_open=True)
    """At most this many replayed samples per new sample of a batch; beyond, the entries are
    drawn in proportion to their weight, each standing for its own weight in expectation
    (ehm.core.observations.memory.threshold_draw; None: all of them). The replay's weight is
    bounded by replay_ratio, the number of entries it comes from is not: on a drive that
    passes its places again they would grow with every pass, and so would the time per scan."""
    pass_retraction: float = setting(0.5, "memory", low=0.0, high=1.0)
    """Share of the occupied evidence in a memory cell that each ray passing through it takes
    back, once rays of two batches have passed it with no new hit near it between
    (ehm.core.observations.passes): a thing that moved away is forgotten within a few scans,
    and the occupied clusters that stood on that evidence forget it in the same measure
    (ehm.core.weights.forgetting). 0 keeps all evidence: the map never forgets, and learns
    static scenes faster."""
    forget_after: float | None = setting(None, "memory", unit="s", low=0.0, low_open=True)
    """Seconds a place may go unseen before what the map learned there starts to fade back to
    unknown (0.5, with the prior's std): from then on its weights, and the past evidence kept
    there, halve every quarter of forget_after (ehm.core.weights.forgetting.fade), so a place
    unseen for twice as long reads close to unknown. For robots that run for hours in places
    that change while they look elsewhere. Every scan then needs its time stamp
    (`integrate(..., time=...)`); a map fades as it learns, up to its latest scan's time. None,
    the default: the map never fades."""

    # Queries (Alg. 3).
    query_intercept: bool = setting(False, "queries")
    """Add the learned intercept (bias) to the query scores. It absorbs the share of free
    samples during training, which the sampling settings set, not the scene; left out, a point
    no cluster reaches reads 0.5 (unknown), as in OctoMap."""
    calibrate: bool = setting(False, "queries")
    """Read the log-odds calibrated: times the one scale that best predicts the evidence of
    the latest batch's rays, drawn afresh after it is learned (ehm.core.weights.calibration).
    Regularised SGD leaves the weights too small, so the raw occupancy reads observed free
    space and hits closer to 0.5 than they are; the scale changes no reading's side of 0.5.
    Off by default: fitted where rays passed, it sharpens the map's weak readings of thinly
    observed space too (what `ehm.diff` reads as changes). False: the raw log-odds, w^T phi."""
    query_mode: QueryMode = setting("batch", "queries")
    """With features 'nearest': 'batch', neighbour search once per group of query points;
    'exact', once per point. With 'support' both are the same."""
    query_cell: float = setting(0.1, "queries", unit="m", low=0.0, low_open=True, length=True)
    """Side of the cubic cells that group query points for one neighbour search, metres."""
    voxel_size: float | None = setting(
        None, "queries", unit="m", low=0.0, low_open=True, length=True
    )
    """Side of the voxels grids, meshes and exports default to, metres (`resolution`); None:
    the resolution the cluster radius stands for (cluster_radius x 0.05 / 0.12). The
    real-time profile's clusters are wider than its resolution, which it keeps here."""
    distance_reach: float = setting(2.0, "queries", unit="m", low=0.0, low_open=True, length=True)
    """Farthest distance `HilbertMap.distance` tells, metres: points farther from every
    obstacle read distance_reach (inside one, -distance_reach). The field it keeps reaches this
    far beyond the map, and an update looks this far around what changed."""

    def __post_init__(self) -> None:
        for field, kind, may_be_off in _fields():
            value = getattr(self, field.name)
            if field.name == "learn_box" or (value is None and may_be_off):
                continue
            _check_type(field, value, kind)
            _check_bounds(field, value, may_be_off)
        self._check_learn_box()
        if not (self.max_range == 0 or self.max_range > self.min_range):
            raise SettingsError(
                f"MapConfig.max_range must be 0 (no limit) or above min_range "
                f"({self.min_range!r} m), got {self.max_range!r}"
            )

    def _check_learn_box(self) -> None:
        """SettingsError unless learn_box is empty or a box's corners; stored as floats."""
        try:
            box = tuple(float(v) for v in self.learn_box)
        except (TypeError, ValueError):
            box = None
        if box is not None and not box:
            object.__setattr__(self, "learn_box", ())
            return
        half = len(box) // 2 if box is not None else 0
        if (
            box is None
            or len(box) not in (4, 6)
            or not all(math.isfinite(v) for v in box)
            or not all(box[i] < box[half + i] for i in range(half))
        ):
            raise SettingsError(
                "MapConfig.learn_box must be empty or a low corner then a high corner, 4 or 6 "
                f"finite numbers with low < high on every axis, got {self.learn_box!r}"
            )
        object.__setattr__(self, "learn_box", box)

    @classmethod
    def for_resolution(
        cls, resolution: float, profile: Profile = "default", **overrides: Any
    ) -> MapConfig:
        """The settings for a map of `resolution` metres of detail, as an OctoMap of that
        voxel size: every length setting (LENGTH_SETTINGS: sample spacing and depths, cluster
        radii, the kernels' smallest spread, query cells) scaled by resolution /
        DEFAULT_RESOLUTION, then `overrides`. Long-range outdoor LiDAR, whose hits lie tens of
        centimetres apart, wants about 0.2.

        profile: 'default', the most accurate, one model for points and grids; 'realtime',
        learning faster (REALTIME: one SGD epoch, crowded hits pooled, free samples far from
        hits thinned, the paper's nearest kernels as features, so that point queries leave out
        kernels grids sum, occupied clusters REALTIME_CLUSTER_SCALE times as wide, the
        resolution kept for outputs in voxel_size).
        Wider clusters read a little more of the space in front of a surface occupied: lower
        near-surface precision, higher recall (measured in the documentation's Resolution
        page)."""
        if not isinstance(resolution, int | float) or not 0.0 < resolution < float("inf"):
            raise SettingsError(
                f"map resolution must be a positive number of metres, got {resolution!r}"
            )
        if profile not in typing.get_args(Profile):
            raise SettingsError(f"profile must be 'default' or 'realtime', got {profile!r}")
        defaults = cls()
        scale = resolution / DEFAULT_RESOLUTION
        scaled = {
            name: getattr(defaults, name) * scale
            for name in LENGTH_SETTINGS
            if getattr(defaults, name) is not None
        }
        if profile == "realtime":
            scaled.update(REALTIME, voxel_size=resolution)
            scaled["cluster_radius"] *= REALTIME_CLUSTER_SCALE
        return defaults.replace(**{**scaled, **overrides})

    @classmethod
    def of(cls, config: MapConfig | None = None, **overrides: Any) -> MapConfig:
        """The settings a map is made with: `config` (None: the defaults) with keyword
        `overrides`; resolution=r and profile=p among them, in place of a config, start from
        for_resolution(r, p)."""
        if "resolution" in overrides or "profile" in overrides:
            if config is not None:
                raise InputError(
                    "give a resolution (and profile) or a config, not both: the config holds "
                    "its resolution and profile's settings"
                )
            resolution = overrides.pop("resolution", DEFAULT_RESOLUTION)
            config = cls.for_resolution(resolution, overrides.pop("profile", "default"))
        base = config if config is not None else cls()
        return base.replace(**overrides) if overrides else base

    @property
    def resolution(self) -> float:
        """The map's detail, metres: the resolution `for_resolution` was given, read back from
        the cluster radius it scaled, or voxel_size where that is set. Grids, meshes and exports
        default to it."""
        if self.voxel_size is not None:
            return self.voxel_size
        return DEFAULT_RESOLUTION * self.cluster_radius / _DEFAULT_CLUSTER_RADIUS

    def replace(self, **overrides: Any) -> MapConfig:
        """A copy with some settings changed; unknown names raise SettingsError."""
        known = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(overrides) - known)
        if unknown:
            hint = (
                ": a map's resolution scales its settings, MapConfig.for_resolution(r)"
                if "resolution" in unknown
                else ""
            )
            raise SettingsError(f"unknown MapConfig setting(s): {', '.join(unknown)}{hint}")
        return dataclasses.replace(self, **overrides)

    @staticmethod
    def may_be_off(name: str) -> bool:
        """Whether setting `name` takes None, which turns it off."""
        return any(f.name == name and off for f, _, off in _fields())

    @staticmethod
    def setting_type(name: str) -> Any:
        """The type setting `name` takes when on (X of X | None)."""
        return next(kind for f, kind, _ in _fields() if f.name == name)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def section(self, name: str) -> dict[str, Any]:
        """The settings of one of SECTIONS, name -> value, in the order MapConfig lists them."""
        if name not in SECTIONS:
            raise SettingsError(f"no section {name!r} of settings; the sections: {SECTIONS}")
        fields = dataclasses.fields(self)
        return {f.name: getattr(self, f.name) for f in fields if f.metadata["section"] == name}

    def to_toml(self) -> str:
        """The settings as a TOML file that `from_toml` reads back to this config: the
        resolution, then a table per section (None written "none")."""
        lines = [
            "# ehm map settings: `ehm map --config FILE` and MapConfig.from_toml read them.",
            f"resolution = {self.resolution!r}",
        ]
        for name in SECTIONS:
            lines += ["", f"[{name}]"]
            lines += [f"{key} = {_toml_value(value)}" for key, value in self.section(name).items()]
        return "\n".join(lines) + "\n"

    @classmethod
    def from_toml(
        cls, text: str, source: str = "settings", resolution: float | None = None
    ) -> MapConfig:
        """The settings of a TOML text: `resolution` (metres; MapConfig.for_resolution, else
        the defaults) then any settings, in their sections' tables or at the top; "none" turns
        off a setting that may be off. `source` names the text in errors; `resolution`, when
        given, replaces the text's, and the text's lengths (LENGTH_SETTINGS) scale with it."""
        import tomllib

        try:
            table = tomllib.loads(text)
        except tomllib.TOMLDecodeError as error:
            raise SettingsError(f"{source}: not TOML ({error})") from None
        given = table.pop("resolution", DEFAULT_RESOLUTION)
        if not (isinstance(given, int | float) and 0.0 < given < math.inf):
            raise SettingsError(f"{source}: resolution must be a positive number of metres")
        resolution = given if resolution is None else resolution
        flat: dict[str, Any] = {}
        sections = {f.name: f.metadata["section"] for f in dataclasses.fields(cls)}
        for key, value in table.items():
            if key in SECTIONS and isinstance(value, dict):
                for name, item in value.items():
                    if sections.get(name) != key:
                        where = f" (it is in [{sections[name]}])" if name in sections else ""
                        raise SettingsError(f"{source}: [{key}] has no setting {name!r}{where}")
                    flat[name] = item
            else:
                flat[key] = value
        for name, value in flat.items():
            if value == "none" and cls.may_be_off(name):
                flat[name] = None
            elif isinstance(value, list):
                flat[name] = tuple(value)
            elif name in LENGTH_SETTINGS and isinstance(value, int | float):
                flat[name] = value * (resolution / given)  # as for_resolution scales
        try:
            return cls.for_resolution(resolution, **flat)
        except SettingsError as error:
            raise SettingsError(f"{source}: {error}") from None

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> MapConfig:
        """Build from a mapping such as `to_dict()` wrote; unknown names raise SettingsError."""
        return cls().replace(**values)


@cache
def _fields() -> tuple[tuple[dataclasses.Field, Any, bool], ...]:
    """Each MapConfig field with its type (X of X | None) and whether it may be None (off),
    read from the annotations once."""
    hints = typing.get_type_hints(MapConfig)
    found = []
    for field in dataclasses.fields(MapConfig):
        kind, hint = hints[field.name], hints[field.name]
        if typing.get_origin(hint) in (typing.Union, types.UnionType):  # X | None: X
            kind = next(k for k in typing.get_args(hint) if k is not type(None))
        found.append((field, kind, kind is not hint))
    return tuple(found)


def _check_type(field: dataclasses.Field, value: Any, kind: Any) -> None:
    """SettingsError unless `value` is of the setting's type `kind`: True or False, an
    integer, a finite number, or one of a Literal's words."""
    name = field.name
    if typing.get_origin(kind) is Literal:
        words = typing.get_args(kind)
        if value not in words:
            listed = " or ".join(repr(w) for w in words)
            raise SettingsError(f"MapConfig.{name} must be {listed}, got {value!r}")
    elif kind is bool:
        if not isinstance(value, bool):
            raise SettingsError(f"MapConfig.{name} must be True or False, got {value!r}")
    elif kind is int:
        if not isinstance(value, int) or isinstance(value, bool):
            low = field.metadata["low"]
            at_least = "" if low is None else f" >= {low:g}"
            raise SettingsError(f"MapConfig.{name} must be an integer{at_least}, got {value!r}")
    elif kind is float:
        finite = isinstance(value, int | float) and not isinstance(value, bool)
        if not (finite and math.isfinite(value)):
            raise SettingsError(f"MapConfig.{name} must be a finite number, got {value!r}")


def _check_bounds(field: dataclasses.Field, value: Any, may_be_off: bool) -> None:
    """SettingsError unless a number keeps its setting's bounds (setting's low and high)."""
    low, high = field.metadata["low"], field.metadata["high"]
    low_open, high_open = field.metadata["low_open"], field.metadata["high_open"]
    unit = field.metadata["unit"]
    if low is not None and high is not None and not (low_open or high_open):
        if not low <= value <= high:
            raise SettingsError(
                f"MapConfig.{field.name} must be between {low:g} and {high:g}, got {value!r}"
            )
        return
    if low is not None and (value <= low if low_open else value < low):
        if low_open and low == 0:
            off = "None or " if may_be_off else ""
            of_unit = " of seconds" if unit == "s" else ""
            wanted = f"{off}a positive number{of_unit}"
        else:
            integer = "an integer " if field.type == "int" else ""
            wanted = f"above {low:g}" if low_open else f"{integer}>= {low:g}"
        raise SettingsError(f"MapConfig.{field.name} must be {wanted}, got {value!r}")
    if high is not None and (value >= high if high_open else value > high):
        wanted = f"below {high:g}" if high_open else f"<= {high:g}"
        in_unit = f" {unit}" if unit == "degrees" else ""
        raise SettingsError(f"MapConfig.{field.name} must be {wanted}{in_unit}, got {value!r}")
    if field.metadata["length"] and 0 < value < SMALLEST_LENGTH:
        raise SettingsError(
            f"MapConfig.{field.name} must be at least {SMALLEST_LENGTH:g} m, got {value!r}"
        )


def _toml_value(value: Any) -> str:
    """A setting's value as TOML writes it."""
    if value is None:
        return '"none"'
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple):
        return "[" + ", ".join(repr(float(v)) for v in value) + "]"
    return repr(value)


_DEFAULT_CLUSTER_RADIUS = MapConfig().cluster_radius
# The settings that are lengths, which for_resolution scales.
LENGTH_SETTINGS = tuple(f.name for f in dataclasses.fields(MapConfig) if f.metadata["length"])
