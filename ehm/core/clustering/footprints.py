"""How wide the fine clusters of a place are: as wide as the spacing of the hits there asks.

A scan's rays spread apart with range: d metres from the sensor its hits lie about d times the
angular spacing of its rays apart (their footprint; ehm.core.sensor.ray_spacing). Near the
sensor a fine cluster of `cluster_radius` gathers many hits; far out it gathers one or two,
and its kernel, as thin as its few samples, covers them and not the surface between them.
With MapConfig.hits_per_radius, the fine clusters of a place are 2^level times as wide: the
least level, up to MAX_LEVEL, whose radius spans that many footprints.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ehm.config import MapConfig
from ehm.core.observations.samples import ScanRays

MAX_LEVEL = 2
"""Fine clusters are at most 2^MAX_LEVEL times `cluster_radius` wide."""


def fine_levels(points: np.ndarray, rays: ScanRays, config: MapConfig) -> np.ndarray:
    """(n,) int64 level of the fine clusters at each of `points` (n, d), metres, world frame:
    from the footprint of the batch's `rays` there (their median angular spacing times the
    distance to the nearest of their origins); all 0 without `hits_per_radius`."""
    levels = np.zeros(len(points), dtype=np.int64)
    if config.hits_per_radius == 0.0 or len(points) == 0 or len(rays) == 0:
        return levels
    # Level 0 holds within `edge` of an origin. The points lie within their rays' reach of one
    # (the clustered ones in regions of cluster_radius the batch's samples reach): a depth
    # camera's batch is all level 0, and no distance is measured.
    edge = config.cluster_radius / (config.hits_per_radius * np.median(rays.ray_spacing))
    reach = rays.lengths.max() + config.occupied_depth + 2.0 * config.cluster_radius
    if reach <= edge:
        return levels
    # A batch's rays come scan by scan, each scan's from one origin.
    origins = rays.origins
    origins = origins[np.r_[True, np.any(origins[1:] != origins[:-1], axis=1)]]
    if len(origins) == 1:
        offsets = points - origins[0]
        distance = np.sqrt(np.einsum("nd,nd->n", offsets, offsets))
    else:
        distance, _ = cKDTree(origins).query(points)
    levels[:] = np.ceil(np.log2(np.maximum(distance / edge, 1.0)))
    return np.minimum(levels, MAX_LEVEL)
