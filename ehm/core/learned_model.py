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
from ehm.core.queries.gradient import logit_gradients
from ehm.core.search.anchors import AnchorLayers
from ehm.core.search.kernel_search import KernelSearch, KernelSums, kernel_search
from ehm.core.snapshot import MapSnapshot
from ehm.core.state import MapState
from ehm.core.weights.uncertainty import logit_variance


@dataclass
class LearnedModel:
    """config; clusters (metres, the map's own frame); memory, the past evidence Alg. 2
    replays; anchors (no layers unless config.anchor_layers > 1); bias_state (2,) float64,
    [bias, its AdaGrad accumulator]; search over the clusters (config.features); rng, the
    generator sampling, clustering and SGD draw from; time, seconds, the latest time stamp
    learned (None without); scale, what queries read the log-odds times (calibrated log-odds,
    ehm.core.weights.calibration; 1 until the first update with config.calibrate)."""

    config: MapConfig
    clusters: ClusterSet
    memory: EvidenceMemory
    search: KernelSearch
    rng: np.random.Generator
    anchors: AnchorLayers = field(default_factory=AnchorLayers)
    bias_state: np.ndarray = field(default_factory=lambda: np.zeros(2))
    time: float | None = None
    scale: float = 1.0

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
            state.scale,
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
        """Log-odds at (n, d) points, metres, and with_variance their variance sums (see
        KernelSearch.sums); NaN rows for points that are not finite."""
        finite, query = finite_rows(points)
        found = self.search.sums(query, self.clusters, self.intercept, with_variance, mode, cell)
        scores = np.full(len(points), np.nan)
        scores[finite] = found.scores
        if not with_variance:
            return KernelSums(scores, found.variance_sums)
        sums = np.full((len(points), 2), np.nan)
        sums[finite] = found.variance_sums
        return KernelSums(scores, sums)

    def log_odds(
        self, points: np.ndarray, mode: str, with_variance: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n,) raw log-odds w^T phi (+ intercept) at (n, d) points, metres, and with_variance
        their (n,) variance under the weights' posterior (else an empty array); NaN rows for
        points not finite. Queries read them times `scale`."""
        found = self.sums(points, with_variance, mode, self.config.query_cell)
        if not with_variance:
            return found.scores, np.zeros(0)
        sums = found.variance_sums
        return found.scores, logit_variance(sums[:, 0], sums[:, 1], self.config.prior_precision)

    def gradients(self, points: np.ndarray, mode: str) -> np.ndarray:
        """(n, d) gradient of the log-odds, 1/m, at (n, d) points, metres, over the kernels a
        query in `mode` reads (ehm.core.queries.gradient); NaN rows for points not finite."""
        finite, query = finite_rows(points)
        indptr, rows = self.search.rows(query, self.clusters, mode)
        clusters, out = self.clusters, np.full(points.shape, np.nan)
        out[finite] = logit_gradients(
            query,
            indptr,
            rows,
            clusters.means,
            clusters.transforms,
            clusters.planar_kernel,
            clusters.weights,
        )
        return out

    def snapshot(self, lineage: object, local_origin: np.ndarray | None = None) -> MapSnapshot:
        """A read-only copy of the kernels and weights, with the means shifted by
        `local_origin` ((d,) metres, the origin of the model's frame in the one wanted; None:
        as kept), and `lineage`, the token of the map's learning history."""
        clusters = self.clusters
        shifted = local_origin is not None and local_origin.any()
        means = clusters.means + local_origin if shifted else clusters.means
        return MapSnapshot(
            means.copy(),
            clusters.transforms.copy(),
            clusters.weights.copy(),
            clusters.precision.copy(),
            clusters.planar_kernel.copy(),
            self.intercept,
            self.config.prior_precision,
            lineage,
            self.scale,
        )


def finite_rows(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n,) bool, which rows of (n, d) points are finite, and those rows, contiguous."""
    finite = np.all(np.isfinite(points), axis=1)
    return finite, np.ascontiguousarray(points[finite])
