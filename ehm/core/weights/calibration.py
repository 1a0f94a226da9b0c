"""Calibrated log-odds: one scale per map that makes its occupancy read as often right as it
claims.

Stochastic gradient descent with L2 regularisation (Eq. 2, ehm.core.weights.sgd) stops with
weights smaller than the evidence supports: held out, points the raw model reads 0.3 are
occupied a few times in a hundred, and a planner with map_server's thresholds (free below 0.196)
sees unknown in observed free space. With MapConfig.calibrate (off by default) the map reads its
log-odds times a scale `a`, the one that best predicts (weighted log loss of sigmoid(a s))
samples drawn afresh from the rays of the batch it just learned: their hits and the points
behind them, occupied, and the free samples along them (not the free sample in front of each
hit, which the sampling places inside the surface's blur on purpose). Drawn afresh, they are not
the cells the weights were fitted to, and the scale they give is close to the one held-out rays
give. A scale changes no reading's side of 0.5: held-out F1, surfaces and meshes at 0.5 stay as
they are. Fitted where rays passed, it sharpens the weak readings of thinly observed space as
well, which is why it is off by default (docs/concepts/uncertainty.md).
"""

from __future__ import annotations

import numpy as np

from ehm.config import MapConfig
from ehm.core.observations.samples import ScanRays, TrainingSamples, ray_randoms, samples_of_rays
from ehm.core.primitives.logistic import sigmoid

# Rays of a batch, and samples of theirs, the scale is fitted on: reading them is most of the
# fit's cost, and the scale is one number (draws of this many from a TUM frame's rays gave
# scales 6 % apart, standard deviation).
CALIBRATION_RAYS = 1024
CALIBRATION_SAMPLES = 4096
# Bounds on the scale. A batch whose samples the map reads all right would drive it without
# bound, and points at the edge of what was seen, read a little below 0.5, would read free.
SCALE_BOUNDS = (0.2, 8.0)
# Newton steps on the scale stop when a step moves it less than this share of it.
TOLERANCE = 1e-4
MAX_STEPS = 50


def calibration_samples(
    rays: ScanRays, config: MapConfig, rng: np.random.Generator
) -> TrainingSamples:
    """Samples of at most CALIBRATION_RAYS of `rays` drawn afresh, at most CALIBRATION_SAMPLES
    of them: hits, the points behind them and free samples along rays (not the free sample in
    front of each hit)."""
    rows = np.sort(rng.choice(len(rays), min(CALIBRATION_RAYS, len(rays)), replace=False))
    some = rays.subset(rows)
    # The front samples are left out: no planes fitted to place them; free samples in the fine
    # band stay flagged as along rays, where the selection below finds them.
    drawn = config.replace(front_stretch=False, fine_free_band=0.0)
    samples = samples_of_rays(some, ray_randoms(len(some), rng), drawn)
    certain = np.flatnonzero(samples.occupied | ~samples.at_surface)
    if len(certain) > CALIBRATION_SAMPLES:
        certain = np.sort(rng.choice(certain, CALIBRATION_SAMPLES, replace=False))
    return samples.subset(certain)


def fitted_scale(log_odds: np.ndarray, occupied: np.ndarray, weight: np.ndarray) -> float:
    """The scale a in SCALE_BOUNDS minimising the weighted log loss of sigmoid(a s) over
    samples of raw log-odds s (n,) float64, labels `occupied` (n,) bool and `weight` (n,)
    float64; 1 where no sample has log-odds other than 0 (nothing seen there yet). Newton's
    method on the loss, convex in a."""
    informative = log_odds != 0.0
    s, label, w = log_odds[informative], occupied[informative], weight[informative]
    if len(s) == 0:
        return 1.0
    low, high = SCALE_BOUNDS
    scale = 1.0
    for _ in range(MAX_STEPS):
        p = sigmoid(scale * s)
        slope = np.sum(w * (p - label) * s)
        curvature = np.sum(w * p * (1.0 - p) * s * s)
        if curvature <= 0.0:  # every sample saturated: the loss is flat in a
            break
        moved = min(max(scale - slope / curvature, low), high)
        if abs(moved - scale) < TOLERANCE * scale:
            return float(moved)
        scale = moved
    return float(scale)
