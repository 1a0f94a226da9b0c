"""Outdoor scenes near surfaces by range: precision and recall of EHM and the peers, 0.1 and 0.2 m.

    python benchmarks/outdoor_ranges.py [--seeds 0,1,2] [--fractions 0.8]
                                        [--datasets street,outdoor_lidar,hillside,power_lines]
                                        [--resolutions 0.1,0.2] [--set name=value ...]

For each simulated outdoor scene, map detail and held-out-rays split (DESIGN.md), EHM (both
profiles, `MapConfig.for_resolution`), OctoMap and wavemap (where built: ../shared/peers/wavemap)
map the training scans; points uniform in balls of 0.3 m around training hits, where a training
ray reached (benchmarks/online_mapping.py), are scored against the scene's exact occupancy:
precision and recall of the occupied class at 0.5, apart for each range bin, the range being
that of the hit a point was drawn around from its scan's origin (points around hits beyond
the last bin, 40 m, are left out). Far hits lie farther apart (a LiDAR's rays spread with
range) and the ground is met at grazing angles there: a map that is right near the sensor
and blurred far away shows it here. Prints one markdown table, mean over seeds, each cell
precision / recall.
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from itertools import pairwise

import numpy as np
from common import heading, markdown_table, settings_text, sweep_arguments
from online_mapping import SIMULATED, near_surface_points_and_ranges
from peers import mapper_of, warm_up
from results_file import run_recorded

from ehm.eval.metrics import precision_recall
from ehm.eval.protocol import held_out_rays

OUTDOOR = ("street", "outdoor_lidar", "hillside", "power_lines")
METHODS = ("ehm", "ehm-realtime", "octomap", "wavemap")
# Range bins, metres from the sensor: [edge, next edge).
RANGE_EDGES = (0.0, 5.0, 10.0, 20.0, 40.0)


def range_bins() -> list[str]:
    """The bins' names, '0-5 m' and on."""
    return [f"{low:g}-{high:g} m" for low, high in pairwise(RANGE_EDGES)]


def measure(
    scans: list, scene, resolution: float, fraction: float, seed: int, settings: dict
) -> dict[str, list[tuple[float, float]] | str]:
    """Per method: (precision, recall) in each range bin (NaN where a bin holds no point or
    no occupied one), or the reason the method was left out."""
    split = held_out_rays(scans, fraction, resolution, seed)
    points, ranges = near_surface_points_and_ranges(
        split.train, 100_000, np.random.default_rng(seed)
    )
    truth = scene.occupied(points)
    bins = np.digitize(ranges, RANGE_EDGES) - 1
    found: dict[str, list[tuple[float, float]] | str] = {}
    for method in METHODS:
        mapper = mapper_of(method, resolution, seed, settings)
        if isinstance(mapper, str):
            found[method] = mapper
            continue
        mapper.build(split.train)
        predicted = mapper.occupancy(points) > 0.5
        found[method] = [
            precision_recall(truth[bins == b], predicted[bins == b])
            if (bins == b).any() and truth[bins == b].any()
            else (float("nan"), float("nan"))
            for b in range(len(RANGE_EDGES) - 1)
        ]
    return found


def cell(pairs: Sequence[tuple[float, float]]) -> str:
    """'precision / recall', means over seeds; '' where a bin holds no point."""
    precision = statistics.fmean(p for p, _ in pairs)
    recall = statistics.fmean(r for _, r in pairs)
    return "" if np.isnan(precision) else f"{precision:.3f} / {recall:.3f}"


def main() -> None:
    sweep = sweep_arguments(
        __doc__.splitlines()[0],
        OUTDOOR,
        with_settings=True,
        fractions="0.8",
        extra={"resolutions": "0.1,0.2"},
    )
    resolutions = [float(r) for r in sweep.extra["resolutions"].split(",")]
    detail = f"seeds {sweep.seeds}, train fractions {sweep.fractions}"
    print(heading("Outdoor scenes by range", detail + settings_text(sweep.settings)))
    for method in METHODS:
        warm_up(method, 3, sweep.settings)
    rows = []
    for name in sweep.datasets:
        data = SIMULATED[name]()
        for resolution in resolutions:
            for fraction in sweep.fractions:
                runs = [
                    measure(data.scans, data.scene, resolution, fraction, seed, sweep.settings)
                    for seed in sweep.seeds
                ]
                for method in METHODS:
                    key = [name, f"{resolution:g}", f"{fraction:.0%}", method]
                    if isinstance(runs[0][method], str):
                        rows.append(key + [runs[0][method]] + [""] * (len(RANGE_EDGES) - 2))
                        continue
                    per_bin = zip(*(run[method] for run in runs), strict=True)
                    rows.append(key + [cell(pairs) for pairs in per_bin])
    header = ["scene", "resolution m", "train", "method", *range_bins()]
    print("### Near-surface precision / recall by range\n")
    print(markdown_table(header, rows, text_columns=4))


if __name__ == "__main__":
    run_recorded(main, __file__)
