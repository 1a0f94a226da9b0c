"""Start-up time: `ehm --help`, `import ehm`, and `import ehm` with the map class loaded.

    python benchmarks/startup.py [--repeats 7]

Each command runs in a fresh interpreter (wall-clock, median of the repeats), so the figures
include Python's own start-up; `python -c pass` is given for reference. Numba's compiled
kernels are cached on disk, as after any first run.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

from common import heading

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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    for command in COMMANDS.values():  # warm the file cache and Numba's cache
        subprocess.run(command, check=True, capture_output=True)
    print(heading("Start-up", f"median of {args.repeats} fresh interpreters"))
    print("| command | seconds | target |")
    print("|---|---:|---|")
    for name, command in COMMANDS.items():
        target = "<= 0.5" if name == "ehm --help" else ""
        print(f"| `{name}` | {wall_seconds(command, args.repeats):.2f} | {target} |")


if __name__ == "__main__":
    main()
