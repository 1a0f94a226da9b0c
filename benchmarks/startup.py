"""Start-up time: `ehm --help`, `import ehm`, and the first `ehm map` after `pip install`.

    python benchmarks/startup.py [--repeats 7] [--no-install]

Each command runs in a fresh interpreter (wall-clock, median of the repeats), so the figures
include Python's own start-up; `python -c pass` is given for reference. Numba's compiled
kernels are cached on disk, as after any first run.

Then the package is installed (not editable) into a new virtual environment, and `ehm map`
runs three times on OctoMap's sample scan: cold (nothing compiled yet), then warm. Numba
reports each compiled kernel it writes to its cache (`NUMBA_DEBUG_CACHE`); a warm run that
writes none compiled nothing.
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

from ehm.eval.datasets.real import data_dir

PROJECT = Path(__file__).resolve().parents[1]
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
        for run in ("cold", "warm", "warm"):
            seconds, compiled = timed_map(ehm_command, scan, Path(tmp) / f"{run}.ehm")
            print(f"| {run} | {seconds:.1f} | {compiled} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--no-install", action="store_true", help="skip the fresh installs")
    args = parser.parse_args()
    print_start_up(args.repeats)
    if not args.no_install:
        print_first_runs()


if __name__ == "__main__":
    main()
