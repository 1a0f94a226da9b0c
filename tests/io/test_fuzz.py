"""Fuzzing every reader: random bytes, truncations, bit flips and edited text made from valid
files of each format. A reader may read a mutated file or refuse it with an EhmError; any other
exception, a long run or a large allocation is a failure. Inputs found to fail are kept as
named cases in test_bad_files.py."""

import importlib.util
import time
import tracemalloc
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

import ehm
from ehm.errors import EhmError
from ehm.io.grid_file import load_grid, save_grid
from ehm.io.points import read_points
from ehm.io.readers import read_scans

MUTATIONS_PER_FILE = 60
# Far more than any of these few-kilobyte files needs, far less than a runaway allocation.
MAX_TRACED_BYTES = 64 * 2**20
MAX_SECONDS = 2.0
TOKENS = [b"nan", b"inf", b"-1", b"0", b"1e308", b"x", b"", b"99999999999", b"-0.0"]


def mutations(data: bytes, rng: np.random.Generator) -> Iterator[bytes]:
    """MUTATIONS_PER_FILE variants of `data`, the same for the same generator."""
    for index in range(MUTATIONS_PER_FILE):
        kind = index % 5
        if kind == 0:  # truncated
            yield data[: int(rng.integers(0, len(data) + 1))]
        elif kind == 1:  # a few bits flipped
            flipped = bytearray(data)
            for _ in range(int(rng.integers(1, 9))):
                position = int(rng.integers(0, len(data)))
                flipped[position] ^= 1 << int(rng.integers(0, 8))
            yield bytes(flipped)
        elif kind == 2:  # random bytes
            yield rng.bytes(int(rng.integers(0, 2 * len(data) + 2)))
        elif kind == 3:  # a whitespace-separated token replaced
            words = data.split(b" ")
            words[int(rng.integers(0, len(words)))] = TOKENS[int(rng.integers(0, len(TOKENS)))]
            yield b" ".join(words)
        else:  # a line dropped or repeated
            lines = data.split(b"\n")
            line = int(rng.integers(0, len(lines)))
            repeat = [lines[line]] * int(rng.integers(0, 3))
            yield b"\n".join(lines[:line] + repeat + lines[line + 1 :])


def targets(input_files, tmp_path) -> dict[str, tuple]:
    """(file to mutate, read call) for every reader and every file a reader reads."""
    found: dict[str, tuple] = {}
    for name, (path, options) in input_files.items():
        read = _scans_reader(path, options)
        if name == "tum":
            found["tum poses"] = (path / "poses.txt", read)
            found["tum depth"] = (path / "depth" / "0.png", read)
        elif name == "7scenes":
            found["7scenes pose"] = (path / "frame-000000.pose.txt", read)
            found["7scenes depth"] = (path / "frame-000001.depth.png", read)
        elif name == "redwood":
            found["redwood trajectory"] = (path / "trajectory.log", read)
            found["redwood camera"] = (path / "camera.json", read)
        elif name == "os.pcap":
            found["ouster capture"] = (path, read)
            found["ouster metadata"] = (path.with_suffix(".json"), read)
        elif name == "000000.bin":
            found["kitti scan"] = (path, read)
            found["kitti poses"] = (options["poses"], read)
            found["kitti calib"] = (path.parent.parent / "calib.txt", read)
        else:
            found[name] = (path, read)
    if importlib.util.find_spec("velodyne_decoder") is not None:
        capture = tmp_path / "hdl32e.pcap"
        capture.write_bytes((Path(__file__).parent / "data" / "hdl32e.pcap").read_bytes())
        found["velodyne capture"] = (capture, lambda: read_scans(capture, format="velodyne"))
    hilbert_map = ehm.HilbertMap(batch_rays=0)
    for scan in read_scans(input_files["b.pcd"][0]):
        hilbert_map.integrate_scan(scan)
    hilbert_map.save(tmp_path / "m.ehm")
    found["m.ehm"] = (tmp_path / "m.ehm", lambda: ehm.load(tmp_path / "m.ehm"))
    save_grid(hilbert_map.grid(resolution=0.5), tmp_path / "g.npz")
    found["g.npz"] = (tmp_path / "g.npz", lambda: load_grid(tmp_path / "g.npz"))
    np.save(tmp_path / "q.npy", np.ones((5, 3)))
    found["q.npy"] = (tmp_path / "q.npy", lambda: read_points(tmp_path / "q.npy", 3))
    np.savetxt(tmp_path / "q.csv", np.ones((5, 3)), delimiter=",")
    found["q.csv"] = (tmp_path / "q.csv", lambda: read_points(tmp_path / "q.csv", 3))
    return found


def _scans_reader(path, options) -> Callable:
    return lambda: read_scans(path, **options)


def test_mutated_files_are_read_or_refused_by_name(input_files, tmp_path):
    rng = np.random.default_rng(2026)
    tried = refused = 0
    for name, (path, read) in targets(input_files, tmp_path).items():
        original = path.read_bytes()
        for variant in mutations(original, rng):
            path.write_bytes(variant)
            tracemalloc.start()
            start = time.perf_counter()
            try:
                read()
            except EhmError as error:
                # A refusal gives its reason after the file's name, never an empty "()".
                reason = str(error).partition(f"{path}: ")[2] or str(error)
                assert reason.strip() and not reason.rstrip().endswith("()"), (name, str(error))
                refused += 1
            except Exception as error:
                pytest.fail(f"{name}: {type(error).__name__}: {error} on {variant[:200]!r}")
            finally:
                seconds = time.perf_counter() - start
                _, peak = tracemalloc.get_traced_memory()
                tracemalloc.stop()
            assert seconds < MAX_SECONDS, (name, seconds, variant[:200])
            assert peak < MAX_TRACED_BYTES, (name, peak, variant[:200])
            tried += 1
        path.write_bytes(original)
    assert tried == len(targets(input_files, tmp_path)) * MUTATIONS_PER_FILE
    assert refused > tried / 3  # most mutations break a file
