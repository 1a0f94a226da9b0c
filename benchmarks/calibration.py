"""How often the occupancy is right when it says so: raw and calibrated log-odds, every data set.

    python benchmarks/calibration.py [--seeds 0,1,2] [--fractions 0.8] [--datasets street,...]

Each data set is split by held-out rays (ehm.eval.protocol.held_out_rays) at its resolution,
and EHM learns the training scans in both profiles of `MapConfig.for_resolution`, calibrated
(MapConfig.calibrate). One map gives both readings: its calibrated log-odds and the raw ones,
w^T phi, which are those over the map's scale. Per reading: the held-out log loss and Brier
score (lower is better), the share of held-out free points read free by map_server's
threshold (occupancy below 0.196) and of held-out hits read occupied (above 0.65), as a
planner asking the map with those thresholds would; and held-out F1 at 0.5, the same for
both. OctoMap at the same resolution (its clamped probabilities, unknown voxels 0.5) for
reference.
"""

from __future__ import annotations

import statistics
import sys

import numpy as np
from common import RESOLUTION, RESOLUTIONS, heading, markdown_table, sweep_arguments
from online_mapping import loaded_datasets
from peers import DATASETS
from results_file import run_recorded

import ehm
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.metrics import f1_score
from ehm.eval.protocol import HeldOutSplit, held_out_rays
from ehm.io.exports import MAP_SERVER_FREE, MAP_SERVER_OCCUPIED
from ehm.pipeline import MappingPipeline

PROFILES = ("default", "realtime")
# Probabilities are kept this far from 0 and 1 in the log loss: a voxel map reads 0 nowhere,
# and a reading that rounds to 0 or 1 in float64 costs as much as one this close.
CLIP = 1e-9


def readings(probability: np.ndarray, split: HeldOutSplit) -> dict[str, float]:
    """Held-out log loss, Brier score, free points read free and hits read occupied (by
    map_server's thresholds) of (n,) occupancy probabilities at the split's points."""
    occupied = split.occupied
    p = np.clip(probability, CLIP, 1.0 - CLIP)
    return {
        "log loss": float(-np.mean(np.where(occupied, np.log(p), np.log1p(-p)))),
        "Brier": float(np.mean((probability - occupied) ** 2)),
        "free read free": float(np.mean(probability[~occupied] < MAP_SERVER_FREE)),
        "hits read occupied": float(np.mean(probability[occupied] > MAP_SERVER_OCCUPIED)),
    }


def measure(split: HeldOutSplit, resolution: float) -> dict[str, dict[str, float]]:
    """Per reading (each profile raw and calibrated, OctoMap): `readings`, held-out F1 and,
    for EHM, the map's scale."""
    found = {}
    for profile in PROFILES:
        config = ehm.MapConfig.for_resolution(resolution, profile, calibrate=True)
        hilbert_map = MappingPipeline(split.train, ehm.HilbertMap(config)).run().hilbert_map
        calibrated = hilbert_map.decision_function(split.points)
        scale = hilbert_map.model_.scale
        for reading, log_odds in (("raw", calibrated / scale), ("calibrated", calibrated)):
            probability = 1.0 / (1.0 + np.exp(-log_odds))
            row = readings(probability, split)
            row["held-out F1"] = f1_score(split.occupied, probability > 0.5)
            row["scale"] = scale
            found[f"ehm {profile}, {reading}"] = row
    octomap = OctoMapMapper(resolution)
    octomap.build(split.train)
    probability = octomap.occupancy(split.points)
    found["octomap"] = readings(probability, split)
    found["octomap"]["held-out F1"] = f1_score(split.occupied, probability > 0.5)
    return found


def main() -> None:
    sweep = sweep_arguments(__doc__.splitlines()[0], DATASETS, fractions="0.8")
    detail = f"seeds {','.join(map(str, sweep.seeds))}, train fractions {sweep.fractions}"
    print(heading("Calibrated occupancy", detail))
    measures = ("log loss", "Brier", "free read free", "hits read occupied", "held-out F1")
    rows = []
    for name, scans, _ in loaded_datasets(sweep.datasets):
        resolution = RESOLUTIONS.get(name, RESOLUTION)
        for fraction in sweep.fractions:
            runs = [
                measure(held_out_rays(scans, fraction, resolution, seed), resolution)
                for seed in sweep.seeds
            ]
            for reading in runs[0]:
                means = {
                    key: statistics.fmean(run[reading][key] for run in runs)
                    for key in runs[0][reading]
                }
                scale = f"{means['scale']:.2f}" if "scale" in means else ""
                values = [f"{means[key]:.4f}" for key in measures]
                rows.append([name, f"{fraction:.0%}", reading, scale, *values])
                print(" | ".join(rows[-1]), file=sys.stderr, flush=True)  # progress
    header = ["data set", "train", "reading", "scale", *measures]
    print(markdown_table(header, rows, text_columns=3))


if __name__ == "__main__":
    run_recorded(main, __file__)
