"""Hilbert maps with localized length-scales as Mappers: EHM, scan by scan or in one batch,
and LLS-HM (Guizilini & Ramos 2016), the same clusters and kernels without batching."""

from __future__ import annotations

from typing import Any

import numpy as np

from ehm.config import DEFAULT_RESOLUTION, MapConfig
from ehm.core.sensor.scan import Scan
from ehm.hilbert_map import HilbertMap
from ehm.pipeline import MappingPipeline

SCAN_BY_SCAN = ("ehm", "ehm-alone", "ehm-realtime")
KINDS = {
    "ehm": (
        "EHM, incremental: one integrate per scan (Alg. 2, 3), small scans gathered into "
        "batches, past evidence replayed",
        {},
    ),
    "ehm-alone": (
        "EHM, incremental, each scan learned from its own samples alone (Alg. 2 as published)",
        {"keep_evidence": False, "batch_rays": 0},
    ),
    "ehm-realtime": (
        "EHM, incremental, the real-time profile: one epoch, wider clusters, fewer samples",
        {"profile": "realtime"},
    ),
    "ehm-batch": ("EHM, single batch: every scan in one fit (Alg. 2, 3)", {}),
    "lls-hm": (
        "LLS-HM (Guizilini & Ramos 2016): EHM's clusters and kernels, one kd-tree search per "
        "training sample and per query point, all scans in one fit",
        {"train_search": "point", "query_mode": "exact"},
    ),
}


class LocalizedMapper:
    """A HilbertMap with the settings for `resolution` metres of detail (see
    MapConfig.for_resolution, and its profile where the kind names one) and `settings`
    (MapConfig overrides) over them, learned as `kind` (see KINDS) says."""

    def __init__(
        self,
        kind: str,
        seed: int = 0,
        resolution: float = DEFAULT_RESOLUTION,
        settings: dict[str, Any] | None = None,
    ) -> None:
        if kind not in KINDS:
            raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
        self.kind = kind
        self.description, overrides = KINDS[kind]
        config = MapConfig.for_resolution(resolution, seed=seed, **overrides)
        self.map = HilbertMap(config.replace(**(settings or {})))
        self.scan_seconds: list[float] = []
        """Wall-clock seconds of each integrate (kinds learned scan by scan only)."""

    def build(self, scans: list[Scan]) -> None:
        run = MappingPipeline(scans, self.map, batch=self.kind not in SCAN_BY_SCAN).run()
        if self.kind in SCAN_BY_SCAN:
            self.scan_seconds = run.scan_seconds

    def occupancy(self, points: np.ndarray) -> np.ndarray:
        return self.map.occupancy(points)

    def memory_bytes(self) -> int:
        return self.map.memory_bytes()
