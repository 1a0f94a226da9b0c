"""Online mapping: EHM scan by scan, without its memory, in one batch, and OctoMap, every data set.

    python benchmarks/online_mapping.py [--seeds 0,1,2] [--fractions 0.8,0.4]
                                        [--datasets warehouse,street,...] [--methods ehm,...]
                                        [--set front_reach=2 ...]

For each data set, train fraction and seed, one held-out-rays split (DESIGN.md) serves the four
methods (`ehm` scan by scan, `ehm-alone` without the sample memory, `ehm-batch` in one
batch, OctoMap): held-out F1 of the occupied class at p = 0.5, every method at the data set's
resolution (0.05 m; on the street 0.2 m, on the outdoor LiDAR scans, the hillside and the
power lines 0.1 m).
On the simulated scenes the same maps are also scored against the exact occupancy at points
near surfaces: uniform in balls of 0.3 m around training hits (both sides of each surface),
kept where some training ray reached; precision, recall and F1 of the occupied class there; and
where the scene has thin solids (posts, rails and wires: at most 0.1 m across along two axes),
the share of points inside them within 0.1 m of a training hit that read occupied (thin
recall). `--set name=value` overrides a MapConfig setting of the EHM methods (as often as
wanted). Each method maps two small scans first, untimed, so compilation is not timed. Prints
markdown tables, mean ± standard deviation over seeds.
"""

from __future__ import annotations

import statistics
import sys
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from common import (
    RESOLUTION,
    RESOLUTIONS,
    heading,
    markdown_table,
    settings_text,
    sweep_arguments,
)
from results_file import run_recorded
from scipy.spatial import cKDTree

from ehm.core.sensor.scan import Scan
from ehm.eval.baselines import make_mapper
from ehm.eval.baselines.localized import KINDS
from ehm.eval.datasets import (
    DataMissingError,
    dense_room,
    hillside,
    load_dataset,
    outdoor_lidar,
    power_lines,
    street,
    virtual_room,
    warehouse,
)
from ehm.eval.datasets.scene import Scene
from ehm.eval.metrics import f1_score, precision_recall
from ehm.eval.protocol import held_out_rays, observed_mask
from ehm.eval.runner import run_method, warm_up

METHODS = ("ehm", "ehm-alone", "ehm-batch", "octomap")
SIMULATED = {
    "virtual_room": virtual_room,
    "warehouse": warehouse,
    "street": street,
    "outdoor_lidar": outdoor_lidar,
    "hillside": hillside,
    "power_lines": power_lines,
    "dense_room": dense_room,
    "dense_room_noisy": lambda: dense_room(noise_std=0.01),
}
DATASETS = (*SIMULATED, "tum_fr2_pioneer_slam2", "pcl_room", "intel_lab", "octomap_scan")
# Test points near surfaces: uniform in balls of this radius around training hits, metres.
NEAR = 0.3
# Solids at most this wide across along two axes are thin (posts, rails, wires), metres.
THIN = 0.1
# Test points drawn inside each thin solid: per metre of its length, and at least.
THIN_POINTS_PER_METRE, THIN_POINTS_LEAST = 100, 400


def near_surface_test_points(scans: Sequence[Scan], n: int, rng: np.random.Generator) -> np.ndarray:
    """(m <= n, d) points uniform in balls of NEAR metres around random hits of `scans`, where
    some ray of `scans` reached."""
    return near_surface_points_and_ranges(scans, n, rng)[0]


def near_surface_points_and_ranges(
    scans: Sequence[Scan], n: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """near_surface_test_points, and (m,) the range of the hit each was drawn around, metres
    from its scan's origin."""
    hits = np.concatenate([s.points_world[s.hit_mask] for s in scans])
    ranges = np.concatenate(
        [np.linalg.norm(s.points_world[s.hit_mask] - s.origin, axis=1) for s in scans]
    )
    d = hits.shape[1]
    directions = rng.normal(size=(n, d))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    radii = NEAR * rng.random(n) ** (1.0 / d)
    drawn = rng.integers(0, len(hits), n)
    points = hits[drawn] + directions * radii[:, None]
    reached = observed_mask(list(scans), points, 0.05)
    return points[reached], ranges[drawn][reached]


def thin_solid_test_points(
    scene: Scene, scans: Sequence[Scan], rng: np.random.Generator
) -> np.ndarray:
    """(m, d) points uniform inside the scene's thin boxes (at most THIN metres across along
    two axes: posts, rails, wires), THIN_POINTS_PER_METRE of their length and at least
    THIN_POINTS_LEAST per box, kept within 0.1 m of a hit of `scans`; (0, d) when the scene
    has none."""
    size = scene.box_max - scene.box_min
    thin = np.sort(size, axis=1)[:, 1] <= THIN
    if not thin.any():
        return np.zeros((0, scene.dim))
    counts = np.maximum(THIN_POINTS_LEAST, THIN_POINTS_PER_METRE * size.max(axis=1)).astype(int)
    points = np.concatenate(
        [
            rng.uniform(low, high, (count, scene.dim))
            for low, high, count in zip(
                scene.box_min[thin], scene.box_max[thin], counts[thin], strict=True
            )
        ]
    )
    hits = np.concatenate([s.points_world[s.hit_mask] for s in scans])
    distance, _ = cKDTree(hits).query(points, distance_upper_bound=0.1)
    return points[np.isfinite(distance)]


def measure(
    name: str,
    scans: list[Scan],
    scene: Scene | None,
    fraction: float,
    seed: int,
    methods: Sequence[str] = METHODS,
    settings: dict[str, Any] | None = None,
) -> dict[str, dict[str, float]]:
    """Measures of each of `methods` on one split: 'held-out F1', and with a scene 'near
    precision', 'near recall', 'near F1', and where it has thin solids 'thin recall'.
    settings: MapConfig overrides for the EHM methods."""
    resolution = RESOLUTIONS.get(name, RESOLUTION)
    split = held_out_rays(scans, fraction, resolution, seed)
    near = truth = None
    thin = np.zeros((0, 1))
    if scene is not None:
        rng = np.random.default_rng(seed)
        near = near_surface_test_points(split.train, 100_000, rng)
        truth = scene.occupied(near)
        thin = thin_solid_test_points(scene, split.train, rng)
    found = {}
    for method in methods:
        mapper = make_mapper(method, resolution, seed, settings if method in KINDS else None)
        probability, build_s, _ = run_method(mapper, split.train, split.points)
        row = {"held-out F1": f1_score(split.occupied, probability > 0.5), "build s": build_s}
        if near is not None:
            predicted = mapper.occupancy(near) > 0.5
            precision, recall = precision_recall(truth, predicted)
            row.update(
                {
                    "near precision": precision,
                    "near recall": recall,
                    "near F1": f1_score(truth, predicted),
                }
            )
        if len(thin):
            row["thin recall"] = float(np.mean(mapper.occupancy(thin) > 0.5))
        found[method] = row
    return found


def scans_and_scene(name: str) -> tuple[list[Scan], Scene | None] | None:
    """The scans of data set `name` and, for a simulated one, its scene; None, with a
    message, for a real data set whose files are absent."""
    if name in SIMULATED:
        data = SIMULATED[name]()
        return data.scans, data.scene
    try:
        return load_dataset(name), None
    except DataMissingError as missing:
        print(f"{name}: left out ({missing})\n")
        return None


def loaded_datasets(names: Sequence[str]) -> Iterator[tuple[str, list[Scan], Scene | None]]:
    """(name, scans, scene) of each of `names` whose data is here (scans_and_scene)."""
    for name in names:
        loaded = scans_and_scene(name)
        if loaded is not None:
            yield name, *loaded


# The methods whose measures near surfaces the second table shows: the peer comparison.
NEAR_METHODS = ("ehm", "octomap")
NEAR_MEASURES = ("near precision", "near recall", "near F1", "thin recall")


def mean_and_spread(values: list[float], digits: int) -> str:
    spread = statistics.stdev(values) if len(values) > 1 else 0.0
    return f"{statistics.fmean(values):.{digits}f}±{spread:.{digits}f}"


def summary_tables(
    results: dict[tuple[str, float], list[dict[str, dict[str, float]]]], methods: Sequence[str]
) -> str:
    """Two markdown tables of `results` (per data set and train fraction, `measure`'s results
    for each seed), mean ± standard deviation over seeds: held-out F1 and build seconds of
    every method, then the measures near surfaces of NEAR_METHODS where there are some."""
    over_seeds = {
        key: {
            method: {
                measure_name: mean_and_spread(
                    [run[method][measure_name] for run in runs],
                    2 if measure_name == "build s" else 3,
                )
                for measure_name in runs[0][method]
            }
            for method in methods
        }
        for key, runs in results.items()
    }
    rows = [
        [name, f"{fraction:.0%}"]
        + [found[method]["held-out F1"] for method in methods]
        + [found[method]["build s"] for method in methods]
        for (name, fraction), found in over_seeds.items()
    ]
    header = ["data set", "train"]
    header += [f"F1 {method}" for method in methods] + [f"build s {method}" for method in methods]
    text = "### Held-out F1 and build seconds\n\n" + markdown_table(header, rows, 2)
    near = [
        [name, f"{fraction:.0%}", method]
        + [found[method].get(measure_name, "") for measure_name in NEAR_MEASURES]
        for (name, fraction), found in over_seeds.items()
        for method in NEAR_METHODS
        if method in found and "near F1" in found[method]
    ]
    if near:
        text += "\n### Near surfaces, against the exact occupancy\n\n"
        text += markdown_table(["data set", "train", "method", *NEAR_MEASURES], near, 3)
    return text


def main() -> None:
    sweep = sweep_arguments(__doc__.splitlines()[0], DATASETS, METHODS, with_settings=True)
    seeds, fractions, methods = sweep.seeds, sweep.fractions, sweep.methods
    settings = settings_text(sweep.settings)
    print(heading("Online mapping", f"seeds {seeds}, train fractions {fractions}{settings}"))
    for method in methods:  # compiled code ready before any build is timed
        for dim in (2, 3):
            warm_up(method, dim)
    results, sizes = {}, []
    for name, scans, scene in loaded_datasets(sweep.datasets):
        sizes.append(f"{name} {len(scans)}, {sum(len(s) for s in scans):,}")
        print(f"{name}...", file=sys.stderr, flush=True)  # progress
        for fraction in fractions:
            results[(name, fraction)] = [
                measure(name, scans, scene, fraction, seed, methods, sweep.settings)
                for seed in seeds
            ]
    print(f"Data sets (scans, rays): {'; '.join(sizes)}.\n")
    print(summary_tables(results, methods))


if __name__ == "__main__":
    run_recorded(main, __file__)
