"""The original Hilbert maps (Ramos & Ott 2015), as a Mapper: logistic regression on one of
three fixed feature maps that approximate a kernel with a single length-scale, trained by
stochastic gradient descent.

- 'fourier': random Fourier features of the RBF kernel (Eq. 6);
- 'nystrom': the Nystrom features of the RBF kernel on inducing points drawn from the
  training samples (Eq. 7);
- 'grid': the sparse kernel k_SP (Eq. 8) on inducing points on a regular grid covering the
  training samples (Eq. 9).

The training samples are the ones EHM learns from (ehm.core.observations.samples with the default
MapConfig), so the comparison is between models, not between samplings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ehm.config import MapConfig
from ehm.core.model.kernels import sparse_kernel_reference
from ehm.core.observations.samples import samples_of_scans
from ehm.core.primitives.logistic import sigmoid
from ehm.core.sensor.scan import Scan
from ehm.core.weights.sgd import EPSILON

FEATURES = ("fourier", "nystrom", "grid")


@dataclass(frozen=True)
class HilbertMapsSettings:
    """Settings of the original Hilbert maps; lengths in metres."""

    length_scale: float = 0.25
    """Length-scale l of the RBF kernel exp(-|x - y|^2 / (2 l^2)) ('fourier', 'nystrom')."""
    fourier_features: int = 2000
    """Random Fourier features M."""
    nystrom_points: int = 1000
    """Inducing points M of the Nystrom features."""
    grid_spacing: float = 0.2
    """Spacing of the inducing grid ('grid')."""
    grid_radius: float = 0.3
    """Radius where k_SP reaches 0 ('grid'); the single length-scale of that feature."""
    max_grid_points: int = 20_000_000
    """Refuse inducing grids larger than this (ValueError)."""
    epochs: int = 2
    """Passes of stochastic gradient descent over the samples (as MapConfig.epochs)."""
    batch_size: int = 256
    """Samples per stochastic gradient step."""
    learning_rate: float = 0.3
    """AdaGrad step size."""
    l2: float = 1e-3
    """L2 regularisation of the weights."""


class FourierFeatures:
    """Phi(x) = sqrt(2 / M) cos(S x + b), S (M, d) ~ N(0, I / l^2), b (M,) ~ U[-pi, pi]
    (Eq. 6; sqrt(2 / M) makes Phi(x).Phi(y) approximate the kernel)."""

    def __init__(self, dim: int, count: int, length_scale: float, rng: np.random.Generator):
        self.frequencies = rng.normal(0.0, 1.0 / length_scale, (count, dim))
        self.phases = rng.uniform(-np.pi, np.pi, count)

    @property
    def size(self) -> int:
        return len(self.phases)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return math.sqrt(2.0 / self.size) * np.cos(points @ self.frequencies.T + self.phases)

    @property
    def nbytes(self) -> int:
        return self.frequencies.nbytes + self.phases.nbytes


def rbf_kernel(a: np.ndarray, b: np.ndarray, length_scale: float) -> np.ndarray:
    """(n, m) exp(-|a_i - b_j|^2 / (2 l^2)) for a (n, d), b (m, d), metres."""
    squared = np.sum(a * a, 1)[:, None] + np.sum(b * b, 1)[None, :] - 2.0 * a @ b.T
    return np.exp(-np.maximum(squared, 0.0) / (2.0 * length_scale**2))


class NystromFeatures:
    """Phi(x) = D^-1/2 V^T k(x, inducing) (Eq. 7), over the eigenpairs (D, V) of the inducing
    points' kernel matrix whose eigenvalues exceed 1e-10 of the largest."""

    def __init__(self, samples: np.ndarray, count: int, length_scale: float, rng):
        chosen = rng.choice(len(samples), size=min(count, len(samples)), replace=False)
        self.inducing = samples[np.sort(chosen)]
        self.length_scale = length_scale
        eigenvalues, eigenvectors = np.linalg.eigh(
            rbf_kernel(self.inducing, self.inducing, length_scale)
        )
        kept = eigenvalues > 1e-10 * eigenvalues.max()
        self.projection = eigenvectors[:, kept] / np.sqrt(eigenvalues[kept])

    @property
    def size(self) -> int:
        return self.projection.shape[1]

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return rbf_kernel(points, self.inducing, self.length_scale) @ self.projection

    @property
    def nbytes(self) -> int:
        return self.inducing.nbytes + self.projection.nbytes


@dataclass(frozen=True)
class SparseRows:
    """Feature vectors with c non-zero candidates per row: columns (n, c) int64 and
    values (n, c) float64; the other entries are 0."""

    columns: np.ndarray
    values: np.ndarray

    def __matmul__(self, weights: np.ndarray) -> np.ndarray:
        return np.sum(self.values * weights[self.columns], axis=1)


def _gradient(
    phi: np.ndarray | SparseRows, error: np.ndarray
) -> tuple[np.ndarray | slice, np.ndarray]:
    """The weights a batch touches and the loss gradient on them, sum_i error_i phi_i."""
    if isinstance(phi, SparseRows):
        touched, column = np.unique(phi.columns, return_inverse=True)
        gradient = np.bincount(
            column.ravel(), (phi.values * error[:, None]).ravel(), minlength=len(touched)
        )
        return touched, gradient
    return slice(None), phi.T @ error


class GridFeatures:
    """Phi(x)_j = k_SP(|x - g_j| / radius) over the nodes g_j of a regular grid (Eq. 9): the
    nodes `spacing` apart covering the samples' bounding box grown by `radius`. Sparse: a
    point only touches the nodes within `radius`."""

    def __init__(self, samples: np.ndarray, spacing: float, radius: float, max_points: int):
        self.spacing, self.radius = spacing, radius
        self.low = np.floor((samples.min(axis=0) - radius) / spacing) * spacing
        high = samples.max(axis=0) + radius
        self.shape = tuple(int(v) for v in np.floor((high - self.low) / spacing) + 1)
        if math.prod(self.shape) > max_points:
            raise ValueError(
                f"inducing grid of {math.prod(self.shape):,} points (shape {self.shape}) is "
                f"larger than max_grid_points={max_points:,}: raise grid_spacing"
            )
        span = math.floor(2.0 * radius / spacing) + 1
        dim = len(self.shape)
        self._offsets = np.stack(np.meshgrid(*[np.arange(span)] * dim, indexing="ij"), -1)
        self._offsets = self._offsets.reshape(-1, dim)

    @property
    def size(self) -> int:
        return math.prod(self.shape)

    def __call__(self, points: np.ndarray) -> SparseRows:
        first = np.ceil((points - self.radius - self.low) / self.spacing).astype(np.int64)
        nodes = first[:, None, :] + self._offsets[None, :, :]  # (n, c, d)
        inside = np.all((nodes >= 0) & (nodes < np.array(self.shape)), axis=2)
        offsets = points[:, None, :] - (self.low + nodes * self.spacing)
        values = sparse_kernel_reference(np.linalg.norm(offsets, axis=2) / self.radius)
        values[~inside] = 0.0
        nodes = np.clip(nodes, 0, np.array(self.shape) - 1)
        columns = np.ravel_multi_index(tuple(np.moveaxis(nodes, 2, 0)), self.shape)
        return SparseRows(columns, values)

    @property
    def nbytes(self) -> int:
        return self.low.nbytes


class HilbertMapsMapper:
    """Hilbert maps with one of FEATURES, trained by mini-batch AdaGrad on the regularised
    logistic loss (Eq. 2-3). As in Eq. 1, p(occupied | x) = sigmoid(w^T Phi(x)): no
    intercept."""

    def __init__(
        self, feature: str, seed: int = 0, settings: HilbertMapsSettings | None = None
    ) -> None:
        if feature not in FEATURES:
            raise ValueError(f"feature must be one of {', '.join(FEATURES)}, got {feature!r}")
        self.feature = feature
        self.settings = settings or HilbertMapsSettings()
        self.seed = seed
        self.features = None
        self.weights = np.zeros(0)

    @property
    def description(self) -> str:
        s = self.settings
        detail = {
            "fourier": f"{s.fourier_features} random Fourier features (Eq. 6), l = "
            f"{s.length_scale} m",
            "nystrom": f"Nystrom features on {s.nystrom_points} inducing points (Eq. 7), l = "
            f"{s.length_scale} m",
            "grid": f"k_SP on a {s.grid_spacing} m grid of inducing points (Eq. 9), radius "
            f"{s.grid_radius} m",
        }[self.feature]
        return f"Hilbert maps (Ramos & Ott 2015), {detail}, SGD"

    def build(self, scans: list[Scan]) -> None:
        rng = np.random.default_rng(self.seed)
        config = MapConfig(seed=self.seed)
        samples = samples_of_scans(scans, config, rng)
        s = self.settings
        dim = samples.points.shape[1]
        if self.feature == "fourier":
            self.features = FourierFeatures(dim, s.fourier_features, s.length_scale, rng)
        elif self.feature == "nystrom":
            self.features = NystromFeatures(samples.points, s.nystrom_points, s.length_scale, rng)
        else:
            self.features = GridFeatures(
                samples.points, s.grid_spacing, s.grid_radius, s.max_grid_points
            )
        self.weights = logistic_sgd(self.features, samples.points, samples.occupied, s, rng)

    def occupancy(self, points: np.ndarray, chunk: int = 65_536) -> np.ndarray:
        if self.features is None:
            raise RuntimeError("build the map before querying it")
        points = np.asarray(points, dtype=np.float64)
        scores = np.concatenate(
            [
                self.features(points[i : i + chunk]) @ self.weights
                for i in range(0, len(points), chunk)
            ]
        )
        return sigmoid(scores)

    def memory_bytes(self) -> int:
        features = 0 if self.features is None else self.features.nbytes
        return features + self.weights.nbytes


def logistic_sgd(
    features,
    points: np.ndarray,
    occupied: np.ndarray,
    settings: HilbertMapsSettings,
    rng: np.random.Generator,
) -> np.ndarray:
    """Weights (M,) of logistic regression on features(points), without intercept, by mini-batch
    AdaGrad over the samples in random order, `settings.epochs` times.

    features: callable (b, d) points -> (b, M) array or SparseRows. Only the weights a
    batch touches are regularised and stepped (all of them for dense features).
    """
    weights = np.zeros(features.size)
    grad_sq = np.zeros(features.size)
    labels = occupied.astype(np.float64)
    rate, l2 = settings.learning_rate, settings.l2
    for _ in range(settings.epochs):
        order = rng.permutation(len(points))
        for start in range(0, len(order), settings.batch_size):
            batch = order[start : start + settings.batch_size]
            phi = features(points[batch])
            error = sigmoid(phi @ weights) - labels[batch]
            touched, loss_grad = _gradient(phi, error)
            grad = loss_grad / len(batch) + l2 * weights[touched]
            grad_sq[touched] += grad * grad
            weights[touched] -= rate * grad / np.sqrt(grad_sq[touched] + EPSILON)
    return weights
