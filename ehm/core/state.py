"""Everything a map has learned, as plain data: what a map file stores and restores."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.observations.memory import EvidenceMemory
from ehm.core.search.anchors import AnchorLayers
from ehm.core.sensor.scan import Scan


@dataclass(frozen=True)
class MapState:
    """config; clusters; anchors (no layers unless config.anchor_layers > 1); bias_state:
    (2,) float64, [bias, its AdaGrad accumulator]; n_scans: scans learned; rng_state: the
    state of the map's random generator (numpy's bit_generator.state), so that a restored map
    continues exactly as the saved one would; None starts it afresh from config.seed. memory:
    the past evidence it replays. waiting: scans given but not learned yet, waiting for their
    batch (config.batch_rays), in the order given. sensor_path: (n, d) float64, metres, world
    frame, the origin of every scan given, in order (empty for maps saved before it was kept).
    time: seconds, the latest time stamp of the scans learned (None without). local_origin:
    (d,) float64, metres, world frame, the point clusters and memory are kept relative to
    (None: the world origin). scale: what queries read the log-odds times (calibrated
    log-odds, ehm.core.weights.calibration)."""

    config: MapConfig
    clusters: ClusterSet
    anchors: AnchorLayers
    bias_state: np.ndarray
    n_scans: int
    rng_state: dict[str, Any] | None
    memory: EvidenceMemory
    waiting: tuple[Scan, ...] = ()
    sensor_path: np.ndarray | None = None
    time: float | None = None
    local_origin: np.ndarray | None = None
    scale: float = 1.0
