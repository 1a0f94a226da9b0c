"""What a map has learned, in its own frame: the clusters and their weights, the memory of
past evidence, the search for each point's kernels, and what reads the log-odds from them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.core.model.features import PointGroups, SparseFeatures
from ehm.core.observations.memory import EvidenceMemory
from ehm.core.search.anchors import AnchorLayers
from ehm.core.search.kernel_search import KernelSearch, KernelSums, kernel_search
from ehm.core.snapshot import MapSnapshot
from ehm.core.state import MapState


@dataclass
class LearnedModel:
    """config; clusters (metres, the map's own frame); memory, the past evidence Alg. 2
    replays; anchors (no layers unless config.anchor_layers > 1); bias_state (2,) float64,
    [bias, its AdaGrad accumulator]; search over the clusters (config.features); rng, the
    generator sampling, clustering and SGD draw from; time, seconds, the latest time stamp
    learned (None without)."""

    config: MapConfig
    clusters: ClusterSet
    memory: EvidenceMemory
    search: KernelSearch
    rng: np.random.Generator
    anchors: AnchorLayers = field(default_factory=AnchorLayers)
    bias_state: np.ndarray = field(default_factory=lambda: np.zeros(2))
    time: float | None = None

    @classmethod
    def empty(cls, config: MapConfig, dim: int) -> LearnedModel:
        """A model of `dim` (2 or 3) axes that has learned nothing, its rng from config.seed."""
        clusters = ClusterSet.empty(dim)
        model = cls(
            config,
            clusters,
            EvidenceMemory.of_config(dim, config),
            kernel_search(config, dim),
            np.random.default_rng(config.seed),
        )
        model.relist(None)
        return model

    @classmethod
    def of_state(cls, state: MapState) -> LearnedModel:
        """The model saved in `state` (shared, not copied), its rng where the state left it."""
        model = cls(
            state.config,
            state.clusters,
            state.memory,
            kernel_search(state.config, state.clusters.dim),
            np.random.default_rng(state.config.seed),
            state.anchors,
            np.array(state.bias_state, dtype=np.float64),
            state.time,
        )
        if state.rng_state is not None:
            model.rng.bit_generator.state = state.rng_state
        model.relist(None)
        return model

    @property
    def rng_state(self) -> dict[str, Any]:
        return self.rng.bit_generator.state

    @property
    def bias(self) -> float:
        return float(self.bias_state[0])

    @property
    def intercept(self) -> float:
        """The log-odds every query adds: the bias when config.query_intercept, else 0."""
        return self.bias if self.config.query_intercept else 0.0

    @property
    def nbytes(self) -> int:
        """Bytes of the clusters, memory, anchors, bias and search."""
        arrays = self.clusters.nbytes + self.memory.nbytes + self.bias_state.nbytes
        return arrays + self.anchors.nbytes + self.search.nbytes

    def relist(self, changed: np.ndarray | None) -> None:
        """Bring the search up to date after the clusters at rows `changed` changed (None:
        all of them)."""
        self.search.relist(self.clusters, self.anchors, changed)

    def features(self, points: np.ndarray, groups: PointGroups | None = None) -> SparseFeatures:
        """Training features of (n, d) points, metres (see KernelSearch.features)."""
        return self.search.features(points, self.clusters, groups)

    def sums(self, points: np.ndarray, with_variance: bool, mode: str, cell: float) -> KernelSums:
        """Log-odds at (n, d) finite points, metres, and their variance sums (see
        KernelSearch.sums)."""
        return self.search.sums(points, self.clusters, self.intercept, with_variance, mode, cell)

    def snapshot(self, lineage: object, local_origin: np.ndarray | None = None) -> MapSnapshot:
        """A read-only copy of the kernels and weights, with the means in the frame whose
        origin is -`local_origin` ((d,) metres; None: as kept), and `lineage`, the token of
        the map's learning history."""
        clusters = self.clusters
        means = clusters.means if local_origin is None else clusters.means + local_origin
        return MapSnapshot(
            means.copy(),
            clusters.transforms.copy(),
            clusters.weights.copy(),
            clusters.precision.copy(),
            clusters.planar_kernel.copy(),
            self.intercept,
            self.config.prior_precision,
            lineage,
        )
