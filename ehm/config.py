"""One validated configuration object: every tunable of a map, with its default and unit."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

from ehm.errors import SettingsError

FeatureSearch = Literal["support", "nearest"]
MergeRule = Literal["pooled", "average"]
QueryMode = Literal["batch", "exact"]
TrainSearch = Literal["group", "point"]
UpdateRule = Literal["sgd", "posterior"]


# The map detail the defaults are set for, metres, and the settings that are lengths: those
# MapConfig.for_resolution scales to another detail.
DEFAULT_RESOLUTION = 0.05
LENGTH_SETTINGS = (
    "free_spacing",
    "surface_margin",
    "occupied_depth",
    "cluster_radius",
    "free_cluster_radius",
    "min_std",
    "query_cell",
    "distance_reach",
)
# The shortest length a setting may take, metres: below it, kernels of that spread
# overflow in double precision.
SMALLEST_LENGTH = 1e-6


@dataclass(frozen=True)
class MapConfig:
    """Settings of an Efficient Hilbert Map.

    Distances are in metres. Defaults suit LiDAR and depth cameras at about 5 cm detail
    (DEFAULT_RESOLUTION); `MapConfig.for_resolution` gives the settings for another detail.
    The measurements behind the defaults chosen between alternatives are in the docs' page
    "Why these defaults" (docs/reference/defaults.md).
    """

    # Which rays are learned, and the training samples drawn from each
    # (ehm.core.observations.samples).
    min_range: float = 0.0
    """Rays shorter than this are left out, metres: returns from the robot itself."""
    max_range: float = 0.0
    """Rays longer than this are cut here and learned as rays without return (free space up
    to max_range, no hit), as OctoMap's maxrange does, metres; 0 for no limit. A sensor's
    glitch far away then costs one ray, not a far cluster."""
    learn_box: tuple[float, ...] = ()
    """Learn only inside this box: its low corner then its high corner, metres, world frame
    (4 numbers in 2D, 6 in 3D); empty, everywhere. Samples outside it are left out and free
    samples are drawn only along the part of each ray inside it, as densely as along the
    whole ray, so a map of a box learns what a map of everything learns there. The tiles of
    a TiledMap are such maps."""
    max_free_samples: int = 1000
    """Most free samples drawn along one ray: a longer ray gets them sparser, so a scan's
    samples are bounded by its rays, never by how far one point lies (at the default
    free_spacing, 1000 samples reach 600 m)."""
    free_spacing: float = 0.6
    """Mean distance between free samples along a ray, metres (density of free samples)."""
    free_thinning: int = 1
    """Free samples farther than two free cluster radii from their ray's hit, and along rays
    without one, lie this many times free_spacing apart, each standing for as many. 1: more
    builds outdoor scenes faster but loses thin posts that rays pass far from their hits."""
    surface_pooling: int = 1
    """The samples behind and in front of hits are gathered in cells this many times as wide
    as the hits' own (ehm.core.observations.evidence; a quarter of a cluster radius). 1: 2
    learns crowded hits (a depth camera's) faster, at the cost of slightly thicker surfaces."""
    surface_margin: float = 0.05
    """Margin in front of each hit, metres: free samples along the ray stop this far before
    it, and one free sample is drawn from a quarter of it to `front_reach` times it in front
    of it."""
    front_reach: float = 1.0
    """How far in front of its hit a hit's free sample may lie, in surface margins: uniform up
    to one margin with 1, denser near the hit beyond (ehm.core.observations.samples.
    front_depth). 1: farther thins surfaces faced head-on, but thin posts seen from afar fade."""
    front_stretch: bool = True
    """Where a batch's hits around a hit lie on a plane, the hit's free sample lies as far off
    the plane as it would on a ray along the plane's normal: 1 / cos of the ray's angle to the
    normal as far along the ray (the cosine floored at 0.3;
    ehm.core.observations.samples.front_stretches). On: ground and walls seen at grazing
    angles read thinner, where rays otherwise leave them thick."""
    occupied_depth: float = 0.15
    """One occupied sample is drawn up to this far behind each hit, metres: surfaces are taken
    to be solid this deep."""

    batch_rays: int = 20_000
    """Scans are gathered until they hold at least this many rays, then learned as one batch
    (one gathering of evidence, one clustering, one SGD run). A query, a grid or `flush()`
    learns the scans still waiting first, so every answer sees every scan given. Small scans
    (a 2D laser's few hundred rays) then share the fixed cost of an update and form their
    clusters together, faster and more accurately than one by one; scans of a LiDAR or a
    depth camera hold more rays and are learned as they come. 0 learns every scan as it
    comes."""

    # Quick-means (Alg. 1).
    cluster_radius: float = 0.12
    """Inner radius r_i of quick-means for occupied samples, metres."""
    outer_radius_factor: float = 1.5
    """Outer radius r_o as a multiple of the inner radius."""
    free_cluster_radius: float = 0.6
    """Inner radius r_i of quick-means for free samples along rays, metres, when clustered
    apart; they form the coarse clusters. Samples around hits use `cluster_radius`."""
    min_cluster_size: int = 4
    """Quick-means drops seeds with fewer samples than this within the outer radius."""
    kmeans_iterations: int = 0
    """Lloyd iterations refining quick-means centres (0 = use quick-means as it is)."""
    cluster_free_apart: bool = True
    """Cluster occupied and free samples separately (True) or together (False)."""

    # Localized length-scale features (Eq. 8, 10-12).
    features: FeatureSearch = "nearest"
    """Which kernels make up a point's feature vector. 'nearest': the paper's Alg. 3, the
    `neighbours` nearest fine and `coarse_neighbours` nearest coarse clusters, searched once
    per group of points (kd-trees or anchor layers); kernels beyond them are left out, so
    point queries differ from grids (Sec. 3.5), which sum every kernel. 'support': every
    kernel that is not zero there, found in a spatial hash of the kernels' supports that is
    updated in time proportional to what changed (ehm.core.search.supports), so training, point
    queries and grids share one model and point queries are faster; 'nearest' stays the
    default while its integrate costs less."""
    length_scale: float = 3.0
    """Kernel support in standard deviations of the cluster (r = 1 at this many sigmas), for
    the kernels of free clusters."""
    occupied_length_scale: float = 3.5
    """The same for the kernels of occupied clusters. Wider than free ones, they reach the hits
    that range noise puts in front of a surface."""
    min_std: float = 0.02
    """Floor on each cluster's standard deviation along any axis, metres."""
    neighbours: int = 8
    """Fine clusters that enter each point's feature vector (k nearest fine centres), with
    features 'nearest'."""
    coarse_neighbours: int = 4
    """Coarse free-space clusters that enter each point's feature vector as well. Coarse
    kernels overlap more than fine ones: more of them bring point queries closer to the
    grid's sum over every kernel (Sec. 3.5), at a query's cost."""

    # Kernel selection (Sec. 3.2).
    planar_ratio: float = 0.1
    """A cluster is planar (a wall, a floor; a line segment in 2D) when its smallest covariance
    eigenvalue is at most this share of the next smallest."""
    planar_kernel: bool = False
    """Planar clusters use the planar-surface kernel (Eq. 13, 1 within two standard deviations
    along each eigen-axis); the others, and all when False, the localized length-scale one.
    Off: it puts the occupied boundary centimetres in front of walls."""
    merge_coplanar: bool = False
    """Orientation clustering (Eq. 14-15): after each update, planar clusters it touched merge
    with planar neighbours of the same scale and label whose normals and positions agree,
    until no more merge. Off: fewer clusters, but less accuracy near surfaces."""
    coplanar_angle: float = 10.0
    """Largest angle between the normals of clusters that merge as co-planar, degrees."""
    coplanar_distance: float = 2.0
    """Largest anisotropic distance (Eq. 14) between clusters that merge as co-planar."""

    # Neighbour search (Sec. 3.1, 3.4), with features 'nearest'.
    anisotropic_search: bool = False
    """Rank the clusters of a point by the radius their kernel gives it, |T_m (x - mu_m)|,
    rather than by the Euclidean distance between the point and their centres. Off: slower
    queries, no more accurate."""
    anisotropic_candidates: int = 3
    """Anisotropic search re-ranks this many times k nearest centres."""
    anchor_layers: int = 1
    """Layers of the cluster hierarchy (Fig. 6): 1 searches the clusters directly (kd-trees);
    each further layer groups the one below into anchors, searched top-down. 1: the same
    neighbours, found faster by the kd-tree."""
    anchor_radius_factor: float = 4.0
    """Inner quick-means radius of the first anchor layer, as a multiple of the clusters'
    radius (`cluster_radius` or `free_cluster_radius`); each further layer multiplies it
    again."""

    # Alg. 2: merging and stochastic gradient descent.
    merge_rule: MergeRule = "pooled"
    """'pooled': exact pooled mean and covariance weighted by sample counts; 'average': the
    paper's mean of means and mean of covariances (Alg. 2 lines 19-20)."""
    merge_threshold: float = 1.0
    """Anisotropic distance (Eq. 14) below which a new cluster merges into the map's."""
    update_rule: UpdateRule = "sgd"
    """How each scan's samples update the weights: 'sgd', AdaGrad stochastic gradient descent on
    the regularised loss (Alg. 2); 'posterior', a Gaussian posterior per weight updated with the
    previous one as prior (ehm.core.weights.posterior). 'sgd': more accurate scan by scan and
    in one batch, and replayed samples would count twice in a posterior that already holds
    them."""
    learning_rate: float = 0.3
    """AdaGrad step size of the stochastic gradient steps ('sgd')."""
    l2: float = 1e-3
    """L2 regularisation of the weights (the R(w) of Eq. 2; 'sgd')."""
    prior_precision: float = 1.0
    """Precision (1 / variance) of a new weight's Gaussian prior, centred on 0: the log-odds
    variance of never-observed space (occupancy std 0.21 at 1; ehm.core.weights.uncertainty), and
    under 'posterior' the prior the first update starts from."""
    keep_evidence: bool = True
    """Keep the evidence of past scans, one weighted mean per cell and kind
    (ehm.core.observations.memory): it is replayed with later scans that reach its place, and what
    formed no cluster yet is clustered again with a later scan's evidence in its cell. False: each
    scan is learned from its own evidence alone, as Alg. 2 does."""
    replay_ratio: float = 1.0
    """Weight of the past evidence replayed with each batch, per unit of the batch's own: from
    the cells around hits as much as the batch has there (times the ratio), the rest from the
    cells along rays, each cell in proportion to the weight it has seen."""
    replay_cap: float | None = 2.0
    """At most this many replayed samples per new sample of a batch; beyond, the entries are
    drawn in proportion to their weight, each standing for its own weight in expectation
    (ehm.core.observations.memory.threshold_draw; None: all of them). The replay's weight is
    bounded by replay_ratio, the number of entries it comes from is not: on a drive that
    passes its places again they would grow with every pass, and so would the time per scan."""
    pass_retraction: float = 0.5
    """Share of the occupied evidence in a memory cell that each ray passing through it takes
    back, once rays of two batches have passed it with no new hit near it between
    (ehm.core.observations.passes): a thing that moved away is forgotten within a few scans,
    and the occupied clusters that stood on that evidence forget it in the same measure
    (ehm.core.weights.forgetting). 0 keeps all evidence: the map never forgets, and learns
    static scenes faster."""
    forget_after: float | None = None
    """Seconds a place may go unseen before what the map learned there starts to fade back to
    unknown (0.5, with the prior's std): from then on its weights, and the past evidence kept
    there, halve every quarter of forget_after (ehm.core.weights.forgetting.fade), so a place
    unseen for twice as long reads close to unknown. For robots that run for hours in places
    that change while they look elsewhere. Every scan then needs its time stamp
    (`integrate(..., time=...)`); a map fades as it learns, up to its latest scan's time. None,
    the default: the map never fades."""
    balance_classes: bool = False
    """Weight occupied and free samples so each class carries half of the loss."""
    epochs: int = 2
    """Passes over each scan's samples: epochs of stochastic gradient descent, or sweeps of
    coordinate descent ('posterior')."""
    train_search: TrainSearch = "group"
    """With features 'nearest': 'group', one neighbour search per quick-means group of
    training samples (Alg. 2); 'point', one per sample, as LLS-HM (Guizilini & Ramos 2016)
    does."""

    # Queries (Alg. 3).
    query_intercept: bool = False
    """Add the learned intercept (bias) to the query scores. It absorbs the share of free
    samples during training, which the sampling settings set, not the scene; left out, a point
    no cluster reaches reads 0.5 (unknown), as in OctoMap."""
    query_mode: QueryMode = "batch"
    """With features 'nearest': 'batch', neighbour search once per group of query points;
    'exact', once per point. With 'support' both are the same."""
    query_cell: float = 0.1
    """Side of the cubic cells that group query points for one neighbour search, metres."""
    distance_reach: float = 2.0
    """Farthest distance `HilbertMap.distance` tells, metres: points farther from every
    obstacle read distance_reach (inside one, -distance_reach). The field it keeps reaches this
    far beyond the map, and an update looks this far around what changed."""

    seed: int = 0
    """Seed of every random choice (sampling, quick-means order, SGD order)."""

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(field.default, bool) and not isinstance(value, bool):
                raise SettingsError(f"MapConfig.{field.name} must be True or False, got {value!r}")
            finite = isinstance(value, int | float) and math.isfinite(value)
            off = value is None and MapConfig.may_be_off(field.name)
            if isinstance(field.default, float) and not finite and not off:
                raise SettingsError(
                    f"MapConfig.{field.name} must be a finite number, got {value!r}"
                )
        self._check_learn_box()
        for name in LENGTH_SETTINGS:
            if 0 < getattr(self, name) < SMALLEST_LENGTH:
                raise SettingsError(
                    f"MapConfig.{name} must be at least {SMALLEST_LENGTH:g} m, "
                    f"got {getattr(self, name)!r}"
                )
        positive = (
            "free_spacing",
            "surface_margin",
            "occupied_depth",
            "cluster_radius",
            "free_cluster_radius",
            "length_scale",
            "occupied_length_scale",
            "min_std",
            "learning_rate",
            "merge_threshold",
            "query_cell",
            "distance_reach",
            "planar_ratio",
            "coplanar_angle",
            "coplanar_distance",
            "anchor_radius_factor",
            "prior_precision",
        )
        for name in positive:
            value = getattr(self, name)
            if not isinstance(value, int | float) or not value > 0:
                raise SettingsError(f"MapConfig.{name} must be a positive number, got {value!r}")
        if not self.front_reach >= 1.0:
            raise SettingsError(f"MapConfig.front_reach must be >= 1, got {self.front_reach!r}")
        if not self.outer_radius_factor >= 1.0:
            raise SettingsError(
                f"MapConfig.outer_radius_factor must be >= 1, got {self.outer_radius_factor!r}"
            )
        integers = (
            ("min_cluster_size", 1),
            ("neighbours", 1),
            ("coarse_neighbours", 0),
            ("epochs", 1),
            ("kmeans_iterations", 0),
            ("anisotropic_candidates", 1),
            ("anchor_layers", 1),
            ("batch_rays", 0),
            ("max_free_samples", 1),
            ("free_thinning", 1),
            ("surface_pooling", 1),
        )
        for name, low in integers:
            value = getattr(self, name)
            if not isinstance(value, int) or value < low:
                raise SettingsError(f"MapConfig.{name} must be an integer >= {low}, got {value!r}")
        if not self.planar_ratio < 1.0:
            raise SettingsError(
                f"MapConfig.planar_ratio must be below 1, got {self.planar_ratio!r}"
            )
        if not self.coplanar_angle < 90.0:
            raise SettingsError(
                f"MapConfig.coplanar_angle must be below 90 degrees, got {self.coplanar_angle!r}"
            )
        if not self.anchor_radius_factor > 1.0:
            raise SettingsError(
                f"MapConfig.anchor_radius_factor must be above 1, got {self.anchor_radius_factor!r}"
            )
        if not isinstance(self.replay_ratio, int | float) or not self.replay_ratio >= 0:
            raise SettingsError(f"MapConfig.replay_ratio must be >= 0, got {self.replay_ratio!r}")
        if self.replay_cap is not None and not self.replay_cap > 0:
            raise SettingsError(
                f"MapConfig.replay_cap must be None or a positive number, got {self.replay_cap!r}"
            )
        if not 0.0 <= self.pass_retraction <= 1.0:
            raise SettingsError(
                f"MapConfig.pass_retraction must be between 0 and 1, got {self.pass_retraction!r}"
            )
        if self.forget_after is not None and not (
            isinstance(self.forget_after, int | float) and 0 < self.forget_after < float("inf")
        ):
            raise SettingsError(
                f"MapConfig.forget_after must be None or a positive number of seconds, "
                f"got {self.forget_after!r}"
            )
        if not self.min_range >= 0:
            raise SettingsError(f"MapConfig.min_range must be >= 0, got {self.min_range!r}")
        if not (self.max_range == 0 or self.max_range > self.min_range):
            raise SettingsError(
                f"MapConfig.max_range must be 0 (no limit) or above min_range "
                f"({self.min_range!r} m), got {self.max_range!r}"
            )
        if self.l2 < 0:
            raise SettingsError(f"MapConfig.l2 must be >= 0, got {self.l2!r}")
        if self.features not in ("support", "nearest"):
            raise SettingsError(
                f"MapConfig.features must be 'support' or 'nearest', got {self.features!r}"
            )
        if self.merge_rule not in ("pooled", "average"):
            raise SettingsError(
                f"MapConfig.merge_rule must be 'pooled' or 'average', got {self.merge_rule!r}"
            )
        if self.update_rule not in ("sgd", "posterior"):
            raise SettingsError(
                f"MapConfig.update_rule must be 'sgd' or 'posterior', got {self.update_rule!r}"
            )
        if self.train_search not in ("group", "point"):
            raise SettingsError(
                f"MapConfig.train_search must be 'group' or 'point', got {self.train_search!r}"
            )
        if self.query_mode not in ("batch", "exact"):
            raise SettingsError(
                f"MapConfig.query_mode must be 'batch' or 'exact', got {self.query_mode!r}"
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
    def for_resolution(cls, resolution: float, **overrides: Any) -> MapConfig:
        """The default settings for a map of `resolution` metres of detail, as an OctoMap of
        that voxel size: every length setting (LENGTH_SETTINGS: sample spacing and depths,
        cluster radii, the kernels' smallest spread, query cells) scaled by resolution /
        DEFAULT_RESOLUTION, then `overrides`. Long-range outdoor LiDAR, whose hits lie tens of
        centimetres apart, wants about 0.2."""
        if not isinstance(resolution, int | float) or not 0.0 < resolution < float("inf"):
            raise SettingsError(
                f"map resolution must be a positive number of metres, got {resolution!r}"
            )
        defaults = cls()
        scale = resolution / DEFAULT_RESOLUTION
        scaled = {name: getattr(defaults, name) * scale for name in LENGTH_SETTINGS}
        return defaults.replace(**{**scaled, **overrides})

    @property
    def resolution(self) -> float:
        """The map's detail, metres: the resolution `for_resolution` was given, read back from
        the cluster radius it scaled. Grids, meshes, exports and distance fields default to it."""
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
        return any(
            f.name == name and f.type.endswith("| None") for f in dataclasses.fields(MapConfig)
        )

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> MapConfig:
        """Build from a mapping such as `to_dict()` wrote; unknown names raise SettingsError."""
        return cls().replace(**values)


_DEFAULT_CLUSTER_RADIUS = MapConfig().cluster_radius
