"""One update of a map (Alg. 2): a batch's evidence learned into its model, one call per step,
each timed as a stage of the paper's Table 2.

The batch's evidence (one weighted sample per cell and kind, ehm.core.observations.evidence)
meets the past evidence of the places it reaches (ehm.core.observations.memory): what has gone
unseen too long fades first (config.forget_after), the occupied evidence its rays pass through
is taken back, what formed no cluster yet joins the clustering, and all of it is replayed with
the new.
"""

from __future__ import annotations

import numpy as np

from ehm.core.clustering.coplanar import merge_coplanar
from ehm.core.clustering.footprints import fine_levels
from ehm.core.clustering.grouping import SampleGroups, group_samples
from ehm.core.clustering.merging import absorb_clusters
from ehm.core.learned_model import LearnedModel
from ehm.core.model.features import PointGroups, group_points_by_key
from ehm.core.observations.memory import Visit
from ehm.core.observations.passes import PASS_REACH_CELLS, hit_again, occupied_passes
from ehm.core.observations.samples import ScanRays, TrainingSamples
from ehm.core.search.kernel_search import query_groups
from ehm.core.timing import StageTimer
from ehm.core.weights.calibration import calibration_samples, fitted_scale
from ehm.core.weights.forgetting import fade, fade_shares, forget, mark_seen, standing_shares
from ehm.core.weights.posterior import update_posterior
from ehm.core.weights.sgd import loss_weights, train_weights, weight_ceilings
from ehm.core.weights.uncertainty import add_curvature


def update(
    model: LearnedModel,
    rays: ScanRays,
    samples: TrainingSamples,
    time: float | None,
    timer: StageTimer,
) -> dict[str, int]:
    """Learn `samples`, the evidence of `rays` taken at `time` (seconds, None without), into
    `model`, in place; returns what changed: clusters new, merged, that forgot passed evidence,
    faded and merged as coplanar, and the samples new and replayed."""
    cfg, clusters, memory = model.config, model.clusters, model.memory
    with timer("memory_lookup"):
        visit = memory.visit(samples)
    with timer("forgetting"):
        faded = fade_unseen(model, time)
        forgetting = retract_passes(model, rays, visit)
    with timer("clustering"):
        pending = memory.pending(visit)
        clustered = samples + pending.samples
        levels = fine_levels(clustered.points, rays, cfg)
        grouped = group_samples(clustered, cfg, model.rng, levels)
    with timer("merging"):
        new = grouped.clusters
        candidates = model.search.merge_candidates(new.means, new.coarse, clusters)
        absorbed = absorb_clusters(clusters, candidates, new, cfg)
    report = {
        "new_clusters": absorbed.n_new,
        "merged_clusters": absorbed.n_merged,
        "forgetting_clusters": forgetting,
        "faded_clusters": faded,
    }
    fading = cfg.forget_after is not None and time is not None
    if fading:
        clusters.seen[absorbed.changed] = time
    changed: np.ndarray | None = absorbed.changed
    if cfg.merge_coplanar:
        with timer("coplanar"):
            merge = merge_coplanar(clusters, absorbed.changed, cfg)
        model.anchors.drop_clusters(merge.source)
        report["coplanar_merged"] = merge.merged
        changed = None  # rows moved into the holes of merged clusters
    with timer("index"):
        if cfg.anchor_layers > 1:
            model.anchors.extend(
                clusters.means,
                clusters.coarse,
                (cfg.cluster_radius, cfg.free_cluster_radius),
                cfg.anchor_radius_factor,
                cfg.anchor_layers - 1,
            )
        model.relist(changed)
    n_new = len(samples)
    with timer("replay"):
        replayed = memory.replay(cfg.replay_ratio, visit, cfg.replay_cap, model.rng)
        report.update(new_samples=n_new, replayed_samples=len(replayed))
        # Shuffled once here, SGD reads the features in order (ehm.core.weights.sgd).
        shuffle = model.rng.permutation(n_new + len(replayed))
        train = (samples.without_scatter() + replayed).subset(shuffle)
        groups = None
        if model.search.shares_searches:
            groups = training_groups(model, grouped, n_new, replayed, shuffle)
    with timer("features"):
        features = model.features(train.points, groups)
    with timer(cfg.update_rule):
        weights = loss_weights(train.occupied, train.weight, cfg.balance_classes)
        if cfg.update_rule == "posterior":
            update_posterior(features, train.occupied, weights, clusters, model.bias_state, cfg)
            np.minimum(clusters.weights, weight_ceilings(clusters, cfg), out=clusters.weights)
        else:
            train_weights(
                features, train.occupied, weights, clusters, model.bias_state, cfg, model.rng
            )
    with timer("precision"):
        # The new samples' curvature, once each: replayed ones were counted when new.
        new_weights = np.where(shuffle < n_new, weights, 0.0)
        add_curvature(features, new_weights, clusters.weights, model.bias, clusters.precision)
    with timer("memory_insert"):
        if fading:
            mark_seen(clusters, features, shuffle < n_new, time)
        memory.mark_clustered(pending, grouped.in_cluster[n_new:])
        memory.insert(visit, grouped.in_cluster[:n_new], np.nan if time is None else time)
    if time is not None:
        model.time = time if model.time is None else max(model.time, time)
    if cfg.calibrate:
        with timer("calibration"):
            model.scale = calibrated_scale(model, rays)
    return report


def calibrated_scale(model: LearnedModel, rays: ScanRays) -> float:
    """The scale of the model's log-odds fitted on samples drawn afresh from `rays`, the batch
    it just learned (ehm.core.weights.calibration), from a generator jumped off the model's, so
    that the model's own draws stay as they were."""
    rng = np.random.Generator(model.rng.bit_generator.jumped())
    samples = calibration_samples(rays, model.config, rng)
    log_odds, _ = model.log_odds(samples.points, model.config.query_mode, False)
    return fitted_scale(log_odds, samples.occupied, samples.weight)


def training_groups(
    model: LearnedModel,
    grouped: SampleGroups,
    n_new: int,
    replayed: TrainingSamples,
    shuffle: np.ndarray,
) -> PointGroups:
    """The groups of the shuffled training samples that share one search: the quick-means
    groups of the `n_new` new samples, and the replayed samples region by region of the
    memory they come from, which spans about what a quick-means group does."""
    new_groups = PointGroups(grouped.groups.group_of_point[:n_new], grouped.groups.centres)
    regions = model.memory.region_keys(replayed)
    groups = new_groups + group_points_by_key(replayed.points, regions)
    return PointGroups(groups.group_of_point[shuffle], groups.centres)


def fade_unseen(model: LearnedModel, time: float | None) -> int:
    """Let what has gone unseen longer than config.forget_after fade, from the latest time
    learned to `time` (ehm.core.weights.forgetting); returns how many clusters faded."""
    forget_after, before = model.config.forget_after, model.time
    if forget_after is None or time is None or before is None or time <= before:
        return 0
    model.memory.fade(fade_shares(model.memory.seen, before, time, forget_after))
    shares = fade_shares(model.clusters.seen, before, time, forget_after)
    return len(fade(model.clusters, shares, model.config.prior_precision))


def retract_passes(model: LearnedModel, rays: ScanRays, visit: Visit) -> int:
    """Take back the memory's occupied evidence that `rays` pass through, where the visit's
    samples bring no new hit to its cell and no hit of `rays` lands near it
    (ehm.core.observations.passes), and let the occupied clusters it stood behind forget it
    in the same measure (ehm.core.weights.forgetting); returns how many clusters forgot
    anything."""
    memory, cfg = model.memory, model.config
    if cfg.pass_retraction == 0 or len(memory) == 0:
        return 0
    reach = PASS_REACH_CELLS * memory.sides[0]
    entries, passes = occupied_passes(memory, rays, reach, cfg.occupied_depth)
    hit = visit.entries[visit.samples.occupied]
    standing = np.isin(entries, hit[hit >= 0])
    searched = np.flatnonzero(~standing)  # the others the batch hits in their own cell
    standing[searched] = hit_again(memory, entries[searched], rays, reach)
    retraction = memory.retract(entries, passes, cfg.pass_retraction, standing)
    if len(retraction.entries) == 0:
        return 0
    near = memory.occupied_near(retraction.entries)
    after = memory.weight[near].astype(np.float64)
    before = after.copy()
    before[np.searchsorted(near, retraction.entries)] = retraction.before
    points = memory.points_at(near)
    features = model.features(points, query_groups(points, cfg.query_mode, cfg.query_cell))
    share = standing_shares(features, before, after, len(model.clusters))
    return len(forget(model.clusters, share, cfg.prior_precision))
