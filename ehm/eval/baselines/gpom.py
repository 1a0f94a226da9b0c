"""Gaussian-process occupancy maps (O'Callaghan & Ramos 2012), as a Mapper.

GP regression on labels +1 (occupied) and -1 (free) with a squared-exponential kernel, on a
random subsample of the training samples EHM learns from, half occupied and half free (the
full set would need an n x n Cholesky factor, and free samples outnumber occupied ones).
The length-scale and noise are chosen by the log marginal likelihood over a fixed grid. The
predictive mean and variance are squashed into a probability by probabilistic least-squares
classification, p = Phi((a mu + b) / sqrt(1 + a^2 var)), with a and b fitted on the
leave-one-out predictions (Rasmussen & Williams 2006, Sec. 6.5).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.optimize import minimize
from scipy.special import log_ndtr, ndtr

from ehm.config import MapConfig
from ehm.core.observations.samples import samples_of_scans
from ehm.core.sensor.scan import Scan
from ehm.eval.baselines.hilbert_maps import rbf_kernel

LENGTH_SCALES = (0.1, 0.2, 0.4, 0.8, 1.6)
"""Candidate length-scales, metres."""
NOISE_STDS = (0.1, 0.3, 1.0)
"""Candidate noise standard deviations, in label units."""


class GPOccupancyMapper:
    """GPOM on `subsample` training samples (fewer when the scans give fewer)."""

    def __init__(self, subsample: int = 2000, seed: int = 0) -> None:
        self.subsample = subsample
        self.seed = seed
        self.inputs = np.zeros((0, 0))
        self.length_scale = self.noise_std = 0.0
        self._factor = np.zeros((0, 0))
        self._alpha = np.zeros(0)
        self._squash = (1.0, 0.0)

    @property
    def description(self) -> str:
        return (
            f"GPOM (O'Callaghan & Ramos 2012) on a random subsample of {self.subsample:,} "
            "training samples (half occupied), squared-exponential kernel, PLSC squashing"
        )

    def build(self, scans: list[Scan]) -> None:
        rng = np.random.default_rng(self.seed)
        config = MapConfig(seed=self.seed)
        samples = samples_of_scans(scans, config, rng)
        chosen = balanced_subsample(samples.occupied, self.subsample, rng)
        self.inputs = samples.points[chosen]
        targets = np.where(samples.occupied[chosen], 1.0, -1.0)
        best = max(
            (self._evidence(targets, ls, noise), ls, noise)
            for ls in LENGTH_SCALES
            for noise in NOISE_STDS
        )
        _, self.length_scale, self.noise_std = best
        covariance = self._covariance()
        factor = cho_factor(covariance, lower=True)
        self._factor = np.tril(factor[0])
        self._alpha = cho_solve(factor, targets)
        inverse_diagonal = np.diag(cho_solve(factor, np.eye(len(targets))))
        loo_mean = targets - self._alpha / inverse_diagonal
        loo_var = 1.0 / inverse_diagonal
        self._squash = plsc_fit(targets, loo_mean, loo_var)

    def _covariance(self, length_scale: float | None = None, noise_std: float | None = None):
        length_scale = self.length_scale if length_scale is None else length_scale
        noise_std = self.noise_std if noise_std is None else noise_std
        kernel = rbf_kernel(self.inputs, self.inputs, length_scale)
        return kernel + noise_std**2 * np.eye(len(self.inputs))

    def _evidence(self, targets: np.ndarray, length_scale: float, noise_std: float) -> float:
        """Log marginal likelihood of the targets (constant term left out)."""
        factor, lower = cho_factor(self._covariance(length_scale, noise_std), lower=True)
        alpha = cho_solve((factor, lower), targets)
        return float(-0.5 * targets @ alpha - np.sum(np.log(np.diag(factor))))

    def occupancy(self, points: np.ndarray, chunk: int = 4096) -> np.ndarray:
        if len(self._alpha) == 0:
            raise RuntimeError("build the map before querying it")
        points = np.asarray(points, dtype=np.float64)
        slope, offset = self._squash
        parts = []
        for start in range(0, len(points), chunk):
            cross = rbf_kernel(points[start : start + chunk], self.inputs, self.length_scale)
            mean = cross @ self._alpha
            v = solve_triangular(self._factor, cross.T, lower=True, check_finite=False)
            variance = np.maximum(1.0 - np.sum(v * v, axis=0), 0.0)
            parts.append(ndtr((slope * mean + offset) / np.sqrt(1.0 + slope**2 * variance)))
        return np.concatenate(parts)

    def memory_bytes(self) -> int:
        return self.inputs.nbytes + self._factor.nbytes + self._alpha.nbytes


def balanced_subsample(occupied: np.ndarray, size: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of up to `size` samples drawn at random without replacement, half of
    them occupied and half free where both classes have enough."""
    occupied_rows, free_rows = np.flatnonzero(occupied), np.flatnonzero(~occupied)
    n_occupied = min(len(occupied_rows), max(size // 2, size - len(free_rows)))
    n_free = min(len(free_rows), size - n_occupied)
    chosen = np.concatenate(
        [
            rng.choice(occupied_rows, n_occupied, replace=False),
            rng.choice(free_rows, n_free, replace=False),
        ]
    )
    return np.sort(chosen)


def plsc_fit(targets: np.ndarray, mean: np.ndarray, variance: np.ndarray) -> tuple[float, float]:
    """Slope a and offset b maximising sum log Phi(y (a mu + b) / sqrt(1 + a^2 var)) over
    predictions mu, var (n,) of targets y (n,) in {-1, +1}."""

    def loss(params: np.ndarray) -> float:
        a, b = params
        return -float(np.sum(log_ndtr(targets * (a * mean + b) / np.sqrt(1 + a * a * variance))))

    result = minimize(loss, np.array([1.0, 0.0]), method="Nelder-Mead")
    return float(result.x[0]), float(result.x[1])
