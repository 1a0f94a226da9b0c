"""Start-up: `ehm --help`, `import ehm`, the first `ehm map` and first queries after `ehm warm`.

    python benchmarks/startup.py [--repeats 7] [--no-install]

Each command runs in a fresh interpreter (wall-clock, median of the repeats), so the figures
include Python's own start-up; `python -c pass` is given for reference. Numba's compiled
kernels are cached on disk, as after any first run.

Then the package is installed (not editable) into a new virtual environment, and `ehm map`
runs three times on OctoMap's sample scan: cold (nothing compiled yet), then warm. Numba
reports each compiled kernel it writes to its cache (`NUMBA_DEBUG_CACHE`); a warm run that
writes none compiled nothing.

In a second new environment, `ehm warm` compiles every kernel; then a new process loads the
sample scan's map and makes each query's and output's first call, timed (target: at most 1 s
each), counting the kernels it compiles (target: none).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import heading
from results_file import run_recorded

from ehm.eval.datasets.real import data_dir

PROJECT = Path(__file__).resolve().parents[1]
# A new process's first call of each query and output on the sample scan's map: it prints
# "name seconds" per call.
FIRST_CALLS = """
import sys, time
import numpy as np
import ehm
from ehm.grid.blocks import block_mesh
from ehm.grid.navigation import projected_navigation_grid
hilbert_map = ehm.HilbertMap.load(sys.argv[1])
rng = np.random.default_rng(0)
low, high = hilbert_map.extent()
points = rng.uniform(low, high, size=(10_000, 3))
origins = np.repeat(hilbert_map.sensor_path[:1], 1000, axis=0)
directions = rng.normal(size=(1000, 3))
directions /= np.linalg.norm(directions, axis=1, keepdims=True)
calls = {
    "occupancy": lambda: hilbert_map.occupancy(points),
    "occupancy with std": lambda: hilbert_map.occupancy(points, return_std=True),
    "gradient": lambda: hilbert_map.gradient(points[:1000]),
    "raycast": lambda: hilbert_map.raycast(origins, directions, 10.0),
    "segment_free": lambda: hilbert_map.segment_free(origins, origins + directions),
    "distance": lambda: hilbert_map.distance(points[:1000]),
    "grid": lambda: hilbert_map.grid(np.stack([low, low + 4.0]), 0.1),
    "mesh (blocks)": lambda: block_mesh(hilbert_map.snapshot(), 0.1, np.stack([low, low + 4.0])),
    "nav2 projection": lambda: projected_navigation_grid(
        hilbert_map, (-1.0, 1.0), np.stack([low[:2], low[:2] + 8.0]), 0.1
    ),
}
for name, call in calls.items():
    start = time.perf_counter()
    call()
    print(name, time.perf_counter() - start)
"""
COMMANDS = {
    "python -c pass (reference)": [sys.executable, "-c", "pass"],
    "ehm --help": [str(Path(sys.executable).with_name("ehm")), "--help"],
    "import ehm": [sys.executable, "-c", "import ehm"],
    "import ehm; ehm.HilbertMap": [sys.executable, "-c", "import ehm; ehm.HilbertMap"],
}


def wall_seconds(command: list[str], repeats: int) -> float:
    """Median wall-clock seconds of running `command` to completion."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def print_start_up(repeats: int) -> None:
    for command in COMMANDS.values():  # warm the file cache and Numba's cache
        subprocess.run(command, check=True, capture_output=True)
    print(heading("Start-up", f"median of {repeats} fresh interpreters"))
    print("| command | seconds | target |")
    print("|---|---:|---|")
    for name, command in COMMANDS.items():
        target = "<= 0.5" if name == "ehm --help" else ""
        print(f"| `{name}` | {wall_seconds(command, repeats):.2f} | {target} |")


def fresh_install(folder: Path) -> Path:
    """A new virtual environment in `folder` with the project installed from its sources, not
    editable; its `ehm` command."""
    subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True)
    pip = [str(folder / "bin" / "python"), "-m", "pip", "install", "--quiet"]
    subprocess.run([*pip, str(PROJECT)], check=True, capture_output=True)
    return folder / "bin" / "ehm"


def timed_map(ehm_command: Path, scan: Path, out: Path) -> tuple[float, int]:
    """Seconds of one `ehm map` of `scan`, and how many entries Numba wrote to its cache."""
    env = {**os.environ, "NUMBA_DEBUG_CACHE": "1"}
    env.pop("NUMBA_CACHE_DIR", None)
    start = time.perf_counter()
    run = subprocess.run(
        [str(ehm_command), "map", str(scan), "-o", str(out)],
        check=True, capture_output=True, text=True, env=env,
    )  # fmt: skip
    seconds = time.perf_counter() - start
    return seconds, run.stdout.count("[cache] data saved to")


def print_first_runs() -> None:
    scan = data_dir() / "octomap_scan" / "scan.dat.bz2"
    print(heading("First `ehm map` after pip install", "OctoMap's sample scan, 88,206 rays"))
    print("| run | seconds | Numba cache entries written |")
    print("|---|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        ehm_command = fresh_install(Path(tmp) / "venv")
        for index, run in enumerate(("cold", "warm", "warm")):
            seconds, compiled = timed_map(ehm_command, scan, Path(tmp) / f"{run}{index}.ehm")
            print(f"| {run} | {seconds:.1f} | {compiled} |")
    print()


def print_first_calls_after_warm() -> None:
    scan = data_dir() / "octomap_scan" / "scan.dat.bz2"
    print(heading("First calls after `ehm warm`", "a new process, OctoMap's sample scan map"))
    env = {**os.environ, "NUMBA_DEBUG_CACHE": "1"}
    env.pop("NUMBA_CACHE_DIR", None)
    with tempfile.TemporaryDirectory() as tmp:
        ehm_command = fresh_install(Path(tmp) / "venv")
        start = time.perf_counter()
        warm = subprocess.run(
            [str(ehm_command), "warm"], check=True, capture_output=True, text=True, env=env
        )
        warm_seconds = time.perf_counter() - start
        map_path = Path(tmp) / "scan.ehm"
        subprocess.run([str(ehm_command), "map", str(scan), "-o", str(map_path)], check=True,
                       capture_output=True, env=env)  # fmt: skip
        python = ehm_command.with_name("python")
        run = subprocess.run(
            [str(python), "-c", FIRST_CALLS, str(map_path)],
            check=True, capture_output=True, text=True, env=env,
        )  # fmt: skip
    first = {
        line.rsplit(" ", 1)[0]: float(line.rsplit(" ", 1)[1])
        for line in run.stdout.splitlines()
        if not line.startswith("[cache]")
    }
    compiled = run.stdout.count("[cache] data saved to")
    print(f"`ehm warm` after install: {warm_seconds:.0f} s, "
          f"{warm.stdout.count('[cache] data saved to')} kernels compiled\n")  # fmt: skip
    print("| first call | seconds | target |")
    print("|---|---:|---|")
    for name, seconds in first.items():
        print(f"| {name} | {seconds:.2f} | <= 1 |")
    print(f"\nkernels compiled by these first calls: {compiled} (target 0)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--no-install", action="store_true", help="skip the fresh installs")
    args = parser.parse_args()
    print_start_up(args.repeats)
    if not args.no_install:
        print_first_runs()
        print_first_calls_after_warm()


if __name__ == "__main__":
    run_recorded(main, __file__)
