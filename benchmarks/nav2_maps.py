"""2D maps for navigation: how nav2's map_server reads the maps EHM and OctoMap export.

    python benchmarks/nav2_maps.py [--seeds 0,1,2] [--fractions 0.8,0.4]

Each 2D data set (the Intel lab, a generated office floor) is split by held-out rays. EHM
learns the training rays scan by scan at 0.05 m (`MapConfig.for_resolution`; ehm-calibrated
with `calibrate` on, its log-odds read calibrated), its navigation grid
(`ehm.grid.navigation`) is exported with `ehm.io.exports.write_map_server` and read back from
the .pgm the way map_server reads it in trinary mode: a pixel p has occupancy
(255 - p) / 255, occupied above 0.65, free below 0.196, unknown between. OctoMap at 0.05 m
gives each pixel the occupancy of its voxel, written to a pixel as round(255 (1 - p))
(unknown voxels grey). Reported per method: the share of held-out free points (ray-observed
free space) read free and read unknown, the share of held-out hits read occupied and read
free, the share of unseen points read free (0.2-1 m behind training hits, along their rays,
where no training ray passed: OctoMap's voxel there is unknown), the share of held-out free
points the map itself reads free (occupancy below 0.196, as a planner asking it would), of
held-out hits it reads occupied (above 0.65) and of the unseen points it reads free, and
held-out F1 at 0.5.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from common import RESOLUTION, heading, markdown_table, sweep_arguments
from PIL import Image
from results_file import run_recorded

import ehm
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.datasets import DataMissingError, load_dataset
from ehm.eval.datasets.simulated import corridor_2d
from ehm.eval.metrics import f1_score
from ehm.eval.protocol import HeldOutSplit, held_out_rays
from ehm.grid.bounds import aligned_bounds
from ehm.grid.navigation import navigation_grid
from ehm.io.exports import (
    MAP_SERVER_FREE,
    MAP_SERVER_OCCUPIED,
    MAP_SERVER_UNKNOWN_PIXEL,
    write_map_server,
)
from ehm.pipeline import MappingPipeline

DATASETS = ("intel_lab", "office_floor")
METHODS = ("ehm", "ehm-calibrated", "octomap")


def office_floor() -> list[ehm.Scan]:
    """A generated 50 m office floor (corridor, rooms with doors, furniture, pillars) seen by
    500 laser scans of 180 rays to 8 m."""
    return corridor_2d(n_scans=500, length=50.0).scans


def trinary(pixels: np.ndarray) -> np.ndarray:
    """map_server's trinary reading of pixels: 1 occupied, 0 free, -1 unknown."""
    occupancy = (255.0 - pixels) / 255.0
    return np.where(
        occupancy > MAP_SERVER_OCCUPIED, 1, np.where(occupancy < MAP_SERVER_FREE, 0, -1)
    )


def ehm_reading(hilbert_map: ehm.HilbertMap, points: np.ndarray) -> np.ndarray:
    """The trinary reading of the map_server export of `hilbert_map` at `points` (n, 2);
    unknown outside the exported image."""
    bounds = aligned_bounds(hilbert_map.extent(), RESOLUTION)
    grid = navigation_grid(hilbert_map, bounds, RESOLUTION)
    with tempfile.TemporaryDirectory() as folder:
        image_path = Path(folder) / "map.pgm"
        write_map_server(grid, image_path)
        image = np.asarray(Image.open(image_path))
    cells = np.floor((points - grid.origin) / RESOLUTION).astype(np.int64)
    inside = np.all((cells >= 0) & (cells < np.array(grid.shape)), axis=1)
    reading = np.full(len(points), -1)
    x, y = cells[inside].T
    reading[inside] = trinary(image[grid.shape[1] - 1 - y, x])
    return reading


def octomap_reading(occupancy: np.ndarray) -> np.ndarray:
    """The trinary reading of OctoMap's voxel occupancies (n,) written as map_server pixels
    (unknown voxels, which read 0.5, grey)."""
    pixels = np.rint(255.0 * (1.0 - occupancy)).astype(np.uint8)
    return trinary(np.where(occupancy == 0.5, MAP_SERVER_UNKNOWN_PIXEL, pixels))


def unseen_points(train: list[ehm.Scan], n: int = 20_000, seed: int = 0) -> np.ndarray:
    """(m, 2) points 0.2-1 m behind random training hits along their rays where OctoMap,
    built from the same scans, has no voxel: space no training ray passed."""
    rng = np.random.default_rng(seed)
    hits = np.concatenate([scan.points_world[scan.hit_mask] for scan in train])
    origins = np.concatenate([np.broadcast_to(s.origin, (int(s.hit_mask.sum()), 2)) for s in train])
    pick = rng.choice(len(hits), n)
    directions = hits[pick] - origins[pick]
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    behind = hits[pick] + directions * rng.uniform(0.2, 1.0, n)[:, None]
    octomap = OctoMapMapper(RESOLUTION)
    octomap.build(train)
    return behind[octomap.occupancy(behind) == 0.5]


def measures(method: str, split: HeldOutSplit) -> list[float]:
    """For `method` learned from the split's training scans: free points read free and read
    unknown, hits read occupied and read free, unseen points read free (map_server's reading
    of its export), free points, hits and unseen points the map's own occupancy reads free,
    occupied and free (map_server's thresholds), and held-out F1 (its occupancy at 0.5)."""
    unseen = unseen_points(split.train)
    points = np.concatenate([split.points, unseen])
    if method.startswith("ehm"):
        calibrate = method == "ehm-calibrated"
        config = ehm.MapConfig.for_resolution(RESOLUTION, calibrate=calibrate)
        hilbert_map = MappingPipeline(split.train, ehm.HilbertMap(config)).run().hilbert_map
        occupancy = hilbert_map.occupancy(points)
        reading = ehm_reading(hilbert_map, points)
    else:
        octomap = OctoMapMapper(RESOLUTION)
        octomap.build(split.train)
        occupancy = octomap.occupancy(points)
        reading = octomap_reading(occupancy)
    n = len(split.points)
    held_out, unseen_reading = reading[:n], reading[n:]
    free, hit = held_out[~split.occupied], held_out[split.occupied]
    shares = [np.mean(free == 0), np.mean(free == -1), np.mean(hit == 1), np.mean(hit == 0)]
    own, unseen = occupancy[:n], occupancy[n:]
    own_shares = [
        np.mean(own[~split.occupied] < MAP_SERVER_FREE),
        np.mean(own[split.occupied] > MAP_SERVER_OCCUPIED),
        np.mean(unseen < MAP_SERVER_FREE),
    ]
    unseen_free = np.mean(unseen_reading == 0)
    return [*shares, unseen_free, *own_shares, f1_score(split.occupied, own > 0.5)]


def main() -> None:
    sweep = sweep_arguments(__doc__.splitlines()[0], DATASETS, METHODS)
    unknown = sorted(set(sweep.methods) - set(METHODS))
    if unknown:
        raise SystemExit(f"unknown method(s) {', '.join(unknown)}; known: {', '.join(METHODS)}")
    rows = []
    for name in sweep.datasets:
        try:
            scans = office_floor() if name == "office_floor" else load_dataset(name)
        except DataMissingError as error:
            print(f"{name}: skipped ({error})")
            continue
        for fraction in sweep.fractions:
            splits = [held_out_rays(scans, fraction, RESOLUTION, seed) for seed in sweep.seeds]
            for method in sweep.methods:
                means = np.mean([measures(method, split) for split in splits], axis=0)
                rows.append([name, f"{fraction:.0%}", method, *(f"{v:.3f}" for v in means)])
                print(" | ".join(rows[-1]), file=sys.stderr, flush=True)  # progress
    detail = f"seeds {','.join(map(str, sweep.seeds))}, {RESOLUTION} m"
    print(heading("map_server's reading of 2D maps", detail))
    header = [
        "data set",
        "train",
        "method",
        "free read free",
        "free read unknown",
        "hits read occupied",
        "hits read free",
        "unseen read free",
        "model: free read free",
        "model: hits read occupied",
        "model: unseen read free",
        "held-out F1",
    ]
    print(markdown_table(header, rows, text_columns=3))


if __name__ == "__main__":
    run_recorded(main, __file__)
