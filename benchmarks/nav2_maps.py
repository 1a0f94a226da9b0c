"""2D maps for navigation: how nav2's map_server reads the maps EHM and OctoMap export.

    python benchmarks/nav2_maps.py [--seeds 0,1,2] [--fractions 0.8,0.4]

Each 2D data set (the Intel lab, a generated office floor) is split by held-out rays. EHM
learns the training rays scan by scan at 0.05 m (`MapConfig.for_resolution`), is exported
with `ehm.io.exports.write_map_server` and read back from the .pgm the way map_server reads
it in trinary mode: a pixel p has occupancy (255 - p) / 255, occupied above 0.65, free below
0.196, unknown between. OctoMap at 0.05 m gives each pixel the occupancy of its voxel,
written to a pixel the same way (unknown voxels grey). Reported per method: the share of
held-out free points (ray-observed free space) read free and read unknown, the share of
held-out hits read occupied and read free, and held-out F1 at 0.5.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from common import RESOLUTION, heading, markdown_table, sweep_arguments
from PIL import Image

import ehm
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.datasets import DataMissingError, load_dataset
from ehm.eval.datasets.simulated import corridor_2d
from ehm.eval.metrics import f1_score
from ehm.eval.protocol import held_out_rays
from ehm.io.exports import (
    MAP_SERVER_FREE,
    MAP_SERVER_OCCUPIED,
    MAP_SERVER_UNKNOWN_PIXEL,
    aligned_bounds,
    write_map_server,
)
from ehm.pipeline import MappingPipeline

DATASETS = ("intel_lab", "office_floor")


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
    """The trinary reading of the map_server export of `hilbert_map` at `points` (n, 2)."""
    bounds = aligned_bounds(hilbert_map.extent(), RESOLUTION)
    grid = hilbert_map.grid(bounds, RESOLUTION)
    with tempfile.TemporaryDirectory() as folder:
        image_path = Path(folder) / "map.pgm"
        write_map_server(grid, image_path)
        image = np.asarray(Image.open(image_path))
    cells = np.floor((points - grid.origin) / RESOLUTION).astype(np.int64)
    cells = np.clip(cells, 0, np.array(grid.shape) - 1)
    return trinary(image[grid.shape[1] - 1 - cells[:, 1], cells[:, 0]])


def octomap_reading(octomap: OctoMapMapper, points: np.ndarray) -> np.ndarray:
    """The trinary reading at `points` (n, 2) of OctoMap's voxels written as map_server
    pixels (unknown voxels grey)."""
    occupancy = octomap.occupancy(points)
    pixels = np.rint(255.0 * (1.0 - occupancy)).astype(np.uint8)
    return trinary(np.where(occupancy == 0.5, MAP_SERVER_UNKNOWN_PIXEL, pixels))


def shares(reading: np.ndarray, occupied: np.ndarray) -> list[float]:
    """Free points read free and unknown; hits read occupied and free."""
    free, hit = reading[~occupied], reading[occupied]
    return [np.mean(free == 0), np.mean(free == -1), np.mean(hit == 1), np.mean(hit == 0)]


def main() -> None:
    sweep = sweep_arguments(__doc__.splitlines()[0], DATASETS, ["ehm", "octomap"])
    rows = []
    for name in sweep.datasets:
        try:
            scans = office_floor() if name == "office_floor" else load_dataset(name)
        except DataMissingError as error:
            print(f"{name}: skipped ({error})")
            continue
        for fraction in sweep.fractions:
            measured = {"ehm": [], "octomap": []}
            for seed in sweep.seeds:
                split = held_out_rays(scans, fraction, RESOLUTION, seed)
                config = ehm.MapConfig.for_resolution(RESOLUTION)
                run = MappingPipeline(split.train, ehm.HilbertMap(config)).run()
                hilbert_map = run.hilbert_map
                f1 = f1_score(split.occupied, hilbert_map.occupancy(split.points) > 0.5)
                reading = ehm_reading(hilbert_map, split.points)
                measured["ehm"].append([*shares(reading, split.occupied), f1])
                octomap = OctoMapMapper(RESOLUTION)
                octomap.build(split.train)
                probability = octomap.occupancy(split.points)
                reading = octomap_reading(octomap, split.points)
                f1 = f1_score(split.occupied, probability > 0.5)
                measured["octomap"].append([*shares(reading, split.occupied), f1])
            for method in sweep.methods:
                means = np.mean(measured[method], axis=0)
                rows.append([name, f"{fraction:.0%}", method, *(f"{v:.3f}" for v in means)])
            print(rows[-2], rows[-1], flush=True)
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
        "held-out F1",
    ]
    print(markdown_table(header, rows, text_columns=3))


if __name__ == "__main__":
    main()
