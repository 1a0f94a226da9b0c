"""The project's PCD reader against pypcd4 (a maintained PCD library): speed on each data kind
and what each does with broken files.

    pip install pypcd4 && python benchmarks/pcd_readers.py

Files: 300,000 points of x y z intensity (float32), binary and ascii, generated here, and the
PCL room scan (binary_compressed) from the data folder; median of 5 reads after a warm-up.
Broken files: truncated binary, an ascii body shorter than POINTS, TYPE X, POINTS 0, corrupt
LZF.
"""

from __future__ import annotations

import statistics
import struct
import tempfile
import time
from pathlib import Path

import numpy as np
from common import heading, markdown_table
from results_file import run_recorded

from ehm.eval.datasets.real import data_dir
from ehm.io.pcd import read_pcd

N_POINTS = 300_000


def header(kind: str, n: int = N_POINTS) -> bytes:
    return (
        "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {kind}\n"
    ).encode()


def readers():
    from pypcd4 import PointCloud

    return {
        "ehm": lambda path: read_pcd(path)[0],
        "pypcd4": lambda path: PointCloud.from_path(path).numpy(("x", "y", "z")),
    }


def median_ms(read, path: Path) -> float:
    read(path)
    times = []
    for _ in range(5):
        start = time.perf_counter()
        read(path)
        times.append(time.perf_counter() - start)
    return 1000 * statistics.median(times)


def outcome(read, path: Path) -> str:
    try:
        points = read(path)
    except Exception as error:
        message = str(error).replace(f"{path.parent}/", "").splitlines()[0]
        return f"{type(error).__name__}: {message[:70]}"
    return f"reads {len(points)} points"


def main() -> None:
    records = np.random.default_rng(0).uniform(-5, 5, (N_POINTS, 4)).astype("<f4")
    body = records.tobytes()
    text = "\n".join(" ".join(f"{v:.6f}" for v in row) for row in records).encode() + b"\n"
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        files = {"binary": header("binary") + body, "ascii": header("ascii") + text}
        paths = {}
        for kind, data in files.items():
            paths[kind] = folder / f"{kind}.pcd"
            paths[kind].write_bytes(data)
        room = data_dir() / "pcl_room" / "room_scan1.pcd"
        if room.exists():
            paths["binary_compressed (PCL room)"] = room
        rows = [
            [kind, *(f"{median_ms(read, path):.1f}" for read in readers().values())]
            for kind, path in paths.items()
        ]
        print(heading("PCD readers", "median ms of 5 reads"))
        print(markdown_table(["file", "ehm ms", "pypcd4 ms"], rows))
        broken = {
            "truncated binary": header("binary") + body[:1000],
            "ascii shorter than POINTS": header("ascii") + b"1 2 3 4\n",
            "TYPE X": header("binary").replace(b"TYPE F", b"TYPE X") + body,
            "POINTS 0": header("binary", 0),
            "corrupt LZF": header("binary_compressed")
            + struct.pack("<II", 8, N_POINTS * 16)
            + b"\xff" * 8,
        }
        rows = []
        for name, data in broken.items():
            path = folder / "broken.pcd"
            path.write_bytes(data)
            rows.append([name, *(outcome(read, path) for read in readers().values())])
        print(markdown_table(["broken file", "ehm", "pypcd4"], rows, text_columns=3))


if __name__ == "__main__":
    run_recorded(main, __file__)
