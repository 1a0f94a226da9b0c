"""Changing scenes: EHM and OctoMap scan by scan in a room where things leave, arrive and walk.

    python benchmarks/changing_scene.py [--seeds 0,1,2] [--set front_reach=2 ...]

A person walks across too; everything is measured in 0.05 m voxels after each scan. The
scenes: ehm.eval.datasets.changing, 14 scans each but the last, by a 64-beam LiDAR
(+-45 degrees) 1.2 m up driving along the room, and by 32-beam (-25 to +15 degrees, 1.2 and
1.9 m up) and 16-beam (+-15 degrees, 1.0 m up) LiDARs on a loop, whose rings are 1.3 and 2
degrees apart: old faces lie between their beams and are met at grazing angles; then, on the
loop, a 0.3 m box in the cart's place (32 beams), a 1.5 m one (16 beams), and the cart coming
back at scan 11 (32 beams); a 2D laser of 360 rays 0.3 m up on the loop, in the room its
plane cuts; and a depth camera (160 x 120 pixels over 87 degrees, range noise 0.25 cm at 1 m
growing with its square) looking ahead twice round the loop, 28 frames, the cart gone after
the first lap. The scores: ehm.eval.change_scores.
Methods: EHM with the defaults (it takes back the evidence rays pass through,
`pass_retraction` 0.5), OctoMap and, on the first scene, EHM keeping all evidence
(`pass_retraction` 0: it never forgets). Prints, per scene and method: the share of the cart's
seen surface still read occupied by the number of scans that have passed through it since it
left (ghosts), the share of the crate's seen surface read occupied by the number of scans that
saw it (and of the cart's, once back), the share of the person's trail read occupied at the
end, and near-surface precision, recall and F1 on the static parts at the end; then build
seconds. `--set name=value` overrides a MapConfig setting of both EHM maps (as often as
wanted; `pass_retraction` stays each one's).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from common import (
    RESOLUTION,
    add_settings_argument,
    heading,
    markdown_table,
    settings_of,
    settings_text,
)
from results_file import run_recorded

import ehm
from ehm.eval.baselines.octree import OctoMapMapper
from ehm.eval.change_scores import ChangeProbe
from ehm.eval.datasets.changing import changing_room
from ehm.eval.runner import warm_up

EHM_SETTINGS = {"ehm": {}, "ehm, pass_retraction 0": {"pass_retraction": 0.0}}
METHODS = (*EHM_SETTINGS, "octomap")
SCANS_THROUGH = (1, 3, 6, 8)
SCANS_SEEN = (1, 3)
LOOP_32 = {"rings": 32, "elevations": (-25.0, 15.0), "path": "loop"}
LOOP_16 = {"rings": 16, "elevations": (-15.0, 15.0), "height": 1.0, "path": "loop"}
SCENES = {
    "64 beams, 1.2 m, line": {},
    "32 beams, 1.2 m, loop": LOOP_32,
    "32 beams, 1.9 m, loop": {**LOOP_32, "height": 1.9},
    "16 beams, 1.0 m, loop": LOOP_16,
    "32 beams, 1.2 m, loop, 0.3 m box": {**LOOP_32, "cart": (0.3, 0.3, 0.3)},
    "16 beams, 1.0 m, loop, 1.5 m box": {**LOOP_16, "cart": (1.5, 1.0, 1.5)},
    "32 beams, 1.2 m, loop, cart back": {**LOOP_32, "returns_at": 11},
    "2D laser, 0.3 m, loop": {"sensor": "laser", "azimuths": 360, "height": 0.3, "path": "loop"},
    "depth camera, 1.2 m, 2 loops": {
        "sensor": "depth", "noise_std": 0.0025, "path": "loop", "laps": 2, "n_scans": 28,
        "departs_at": 14, "arrives_at": 18, "walk": (2, 12),
    },
}  # fmt: skip


def methods_of(scene: str) -> tuple[str, ...]:
    """The methods run on `scene`: the one that never forgets on the first only."""
    return METHODS if scene == next(iter(SCENES)) else ("ehm", "octomap")


def run(scene: str, seed: int, settings: dict[str, Any] | None = None) -> dict[str, dict]:
    """Each method's measures on the changing room of SCENES[scene] drawn with `seed`;
    `settings`, MapConfig overrides over each EHM method's."""
    dataset = changing_room(seed=seed, **SCENES[scene])
    results = {}
    for method in methods_of(scene):
        probe = ChangeProbe(dataset, RESOLUTION, np.random.default_rng(seed))
        if method in EHM_SETTINGS:
            config = ehm.MapConfig.for_resolution(
                RESOLUTION, **{**(settings or {}), **EHM_SETTINGS[method]}
            )
            hilbert_map = ehm.HilbertMap(config)
            learn, occupancy = hilbert_map.integrate_scan, hilbert_map.occupancy
        else:
            octomap = OctoMapMapper(RESOLUTION)
            octomap.build([])
            learn, occupancy = octomap.insert, octomap.labels
        seconds = 0.0
        for i, scan in enumerate(dataset.scans):
            start = time.perf_counter()
            learn(scan)
            occupancy(scan.origin[None])  # learns any scan waiting for its batch
            seconds += time.perf_counter() - start
            last = probe.measure(i, occupancy)
        results[method] = {"probe": probe, "last": last, "seconds": seconds}
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", default="0")
    add_settings_argument(parser)
    args = parser.parse_args()
    seeds, settings = [int(s) for s in args.seeds.split(",")], settings_of(args)
    warm_up("ehm", 3)
    print(heading("Changing room", f"seeds {seeds}" + settings_text(settings)))
    header = (
        ["scene", "method"]
        + [f"ghosts after {k}" for k in SCANS_THROUGH]
        + [f"crate after {k}" for k in SCANS_SEEN]
        + [f"back after {k}" for k in SCANS_SEEN]
        + ["trail", "near precision", "near recall", "near F1", "build s"]
    )
    rows = []
    for scene in SCENES:
        runs = [run(scene, seed, settings) for seed in seeds]
        rows += [[scene, *scores(runs, method)] for method in methods_of(scene)]
    print(markdown_table(header, rows, text_columns=2))


def scores(runs: list[dict[str, dict]], method: str) -> list[str]:
    """The row of `method`'s measures, each the mean over `runs` (see `run`)."""
    probes = [r[method]["probe"] for r in runs]
    shares = [
        _mean_share([p.ghost_tally for p in probes], SCANS_THROUGH),
        _mean_share([p.arrival_tally for p in probes], SCANS_SEEN),
        _mean_share([p.return_tally for p in probes], SCANS_SEEN),
    ]
    last = {key: np.mean([r[method]["last"][key] for r in runs]) for key in runs[0][method]["last"]}
    seconds = np.mean([r[method]["seconds"] for r in runs])
    return (
        [method]
        + [_share_text(share) for tally in shares for share in tally]
        + [f"{last[k]:.3f}" for k in ("trail", "near precision", "near recall", "near F1")]
        + [f"{seconds:.2f}"]
    )


def _mean_share(tallies: list, counts: tuple[int, ...]) -> list[float]:
    """The mean over `tallies` (ehm.eval.change_scores.Tally) of the share read occupied after
    each of `counts` scans, over the runs where it was read (NaN where in none)."""
    means = []
    for k in counts:
        read = [share for tally in tallies if np.isfinite(share := tally.share(k))]
        means.append(float(np.mean(read)) if read else float("nan"))
    return means


def _share_text(share: float) -> str:
    """A share with three decimals; blank where there is none (NaN)."""
    return f"{share:.3f}" if np.isfinite(share) else ""


if __name__ == "__main__":
    run_recorded(main, __file__)
