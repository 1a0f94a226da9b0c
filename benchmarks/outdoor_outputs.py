"""Outputs of an outdoor LiDAR map (.bt, .ot, nav2 .pgm, mesh, distances): time, peak memory.

    python benchmarks/outdoor_outputs.py [--resolutions 0.2,0.1,0.05]

The map is one real sweep of a 128-beam Ouster OS-0 (ouster-sdk's test capture in the shared
data, returns out to 128 m), mapped from its pcap by `ehm map --resolution R`; every output
then runs as a user runs it, a fresh `ehm` process with nothing but the map and the output
named, so each time holds reading the map and loading the compiled kernels from their cache
(each command runs once before it is timed). Peak memory is the process's maximum resident
set. The distance query asks 2,000 points drawn within 10 m of the sensor, 0.5-2.5 m above
the floor. Results go to benchmarks/results/outdoor_outputs_records.json.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import heading, markdown_table
from results_file import run_recorded

from ehm.eval.datasets.real import data_dir

CAPTURE = Path("ouster_pcap") / "OS-0-128-U1_v2.3.0_1024x10.pcap"
RESULTS = Path(__file__).parent / "results" / "outdoor_outputs_records.json"
EHM = str(Path(sys.executable).with_name("ehm"))


def run(args: list[str]) -> tuple[float, float, str]:
    """Seconds, peak resident memory (GiB) and stderr of one `ehm` process; raises on failure."""
    start = time.perf_counter()
    process = subprocess.Popen(
        [EHM, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    errors = process.stderr.read()
    process.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"ehm {' '.join(args)} failed:\n{errors}")
    return seconds, usage.ru_maxrss / 2**20, errors


def measure(capture: Path, resolution: float, folder: Path) -> list[dict]:
    map_path = folder / f"sweep_{resolution:g}.ehm"
    points, distances = folder / "near_sensor.npy", folder / "distances.npy"
    rng = np.random.default_rng(0)
    offsets = rng.uniform([-10.0, -10.0, -1.4], [10.0, 10.0, 0.6], (2000, 3))
    np.save(points, offsets)  # the sensor at the origin, the floor 1.9 m under it
    outputs = {
        "map": ["map", str(capture), "-o", str(map_path), "--resolution", str(resolution)],
        ".bt": ["export", str(map_path), "-o", str(folder / "sweep.bt")],
        ".ot": ["export", str(map_path), "-o", str(folder / "sweep.ot")],
        "mesh": ["mesh", str(map_path), "-o", str(folder / "sweep.ply")],
        "nav2 .pgm": ["export", str(map_path), "-o", str(folder / "sweep.pgm")],
        "distance": ["query", str(map_path), str(points), "--distance", "-o", str(distances)],
    }
    records = []
    for name, args in outputs.items():
        try:
            run([*args, "--force"])  # warms the kernel cache; the map is written
            seconds, gib, _ = run([*args, "--force"])
            failure = None
        except RuntimeError as error:
            seconds, gib, failure = float("nan"), float("nan"), str(error).splitlines()[-1]
        record = {"resolution": resolution, "output": name, "seconds": seconds, "peak_gib": gib}
        if name == "distance" and failure is None:
            distance = np.load(distances)
            record["distances_told"] = float(np.mean(np.isfinite(distance)))
            record["median_distance_m"] = float(np.median(distance))
        if failure:
            record["failure"] = failure
        records.append(record)
        print(f"  {resolution} m {name}: {seconds:.1f} s, {gib:.2f} GiB {failure or ''}",
              file=sys.stderr)  # progress; the table follows  # fmt: skip
    return records


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolutions", default="0.2,0.1,0.05")
    args = parser.parse_args()
    capture = data_dir() / CAPTURE
    if not capture.exists():
        sys.exit(f"skipped: {capture} not found (set EHM_DATA_DIR to the data folder)")
    print(heading("Outdoor outputs", "one 128-beam sweep, a fresh ehm process per output"))
    records = []
    with tempfile.TemporaryDirectory() as folder:
        for resolution in map(float, args.resolutions.split(",")):
            records += measure(capture, resolution, Path(folder))
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(records, indent=1) + "\n")
    rows = [
        [
            f"{r['resolution']:g} m",
            r["output"],
            f"{r['seconds']:.1f}" if "failure" not in r else "refused",
            f"{r['peak_gib']:.2f}" if "failure" not in r else "",
            r.get("failure", "")
            or (
                f"{r['distances_told']:.0%} told, median {r['median_distance_m']:.2f} m"
                if "distances_told" in r
                else ""
            ),
        ]
        for r in records
    ]
    print(markdown_table(["resolution", "output", "s", "peak GiB", "note"], rows, 2))


if __name__ == "__main__":
    run_recorded(main, __file__)
