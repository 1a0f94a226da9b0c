"""Building tiled maps on Dask: the same tiles as in one process, written tile by tile, read
by the workers from the scans' files, updated where new scans cross."""

import os
import subprocess
import sys

import numpy as np
import pytest

import ehm
from ehm.errors import InputError
from ehm.io.readers import ScanFiles
from ehm.tiles import TiledMap
from ehm.tiles.build import dask_client

distributed = pytest.importorskip("dask.distributed")

TILE, OVERLAP = 3.0, 1.0


@pytest.fixture(scope="module")
def client():
    with dask_client(None, 2) as local:
        yield local


@pytest.fixture(scope="module")
def in_process(scans):
    tiled = TiledMap(TILE, OVERLAP)
    for scan in scans:
        tiled.integrate_scan(scan)
    return tiled


def parts(scan, n):
    """One scan as n scans of every n-th ray, so that builds have scans to share out."""
    return [scan.subset(np.arange(len(scan)) % n == i) for i in range(n)]


@pytest.fixture(scope="module")
def scans(room):
    return parts(room.scans[0], 6)


def probe_points(n=20_000):
    return np.random.default_rng(5).uniform([-4.0, -3.0, 0.0], [4.0, 3.0, 3.0], (n, 3))


class Recorder:
    def __init__(self):
        self.binned, self.learned = [], []

    def binning(self, done, total):
        self.binned.append((done, total))

    def learning(self, done, total, result):
        self.learned.append((done, total, None if result is None else result.key))


def test_a_dask_build_learns_what_one_process_learns(client, scans, in_process):
    tiled = TiledMap(TILE, OVERLAP)
    recorder = Recorder()
    report = tiled.build(scans, client=client, observer=recorder)
    assert tiled.tile_keys == in_process.tile_keys
    points = probe_points()
    np.testing.assert_array_equal(tiled.occupancy(points), in_process.occupancy(points))
    np.testing.assert_array_equal(tiled.sensor_path, in_process.sensor_path)
    assert (report.n_scans, report.workers) == (len(scans), 2)
    assert report.n_rays == sum(len(scan) for scan in scans)
    assert sorted(tile.key for tile in report.tiles) == tiled.tile_keys
    assert recorder.binned[-1] == (len(scans), len(scans))
    assert [done for done, _, _ in recorder.learned] == list(range(tiled.n_tiles + 1))
    assert {task.worker_pid for task in report.tasks} <= set(client.run(os.getpid).values())


def test_tiles_go_to_the_map_directory_as_they_come(client, scans, in_process, tmp_path):
    tiled = TiledMap(TILE, OVERLAP)
    tiled.build(scans, client=client, directory=tmp_path / "room.ehm", block=1)
    assert tiled.n_loaded_tiles == 0
    files = sorted(p.name for p in (tmp_path / "room.ehm" / "tiles").iterdir())
    assert len(files) == tiled.n_tiles
    loaded = ehm.load(tmp_path / "room.ehm")
    points = probe_points(5000)
    np.testing.assert_array_equal(loaded.occupancy(points), in_process.occupancy(points))
    assert loaded.n_scans_ == len(scans)


def test_workers_read_the_scans_files_themselves(client, scans, tmp_path):
    """xyz files in the sensor frame, placed by a poses file: the workers read each one."""
    paths, poses = [], []
    for i, scan in enumerate(scans[:4]):
        path = tmp_path / f"scan{i}.xyz"
        np.savetxt(path, scan.points_world[scan.hit_mask] - scan.origin)
        paths.append(path)
        poses.append(" ".join(f"{v:.17g}" for v in np.c_[np.eye(3), scan.origin].ravel()))
    (tmp_path / "poses.txt").write_text("\n".join(poses) + "\n")
    files = ScanFiles(paths, poses=tmp_path / "poses.txt")
    on_dask = TiledMap(TILE, OVERLAP)
    on_dask.build(files, client=client)
    here = TiledMap(TILE, OVERLAP)
    for scan in files:
        here.integrate_scan(scan)
    points = probe_points(5000)
    np.testing.assert_array_equal(on_dask.occupancy(points), here.occupancy(points))


def test_new_scans_relearn_only_the_tiles_they_cross(client, scans, tmp_path):
    TiledMap(TILE, OVERLAP).build(scans[:3], client=client, directory=tmp_path / "m.ehm")
    before = ehm.load(tmp_path / "m.ehm")
    corner = scans[3].subset(np.all(scans[3].points_world[:, :2] > [2.5, 1.5], axis=1))
    report = before.build([corner], client=client)
    after = ehm.load(tmp_path / "m.ehm")
    relearned = sorted(tile.key for tile in report.tiles)
    assert 0 < len(relearned) < before.n_tiles / 2
    for key in after.tile_keys:
        expected = 2 if key in relearned else 1
        assert after.tile_record(key).version == expected
    assert after.n_scans_ == 4


def test_a_local_cluster_is_made_and_closed_when_no_client_is_given(scans):
    tiled = TiledMap(TILE, OVERLAP)
    report = tiled.build(scans[:1], workers=1)
    assert report.workers == 1 and tiled.n_tiles > 0


def test_bad_builds_are_refused(client, scans, monkeypatch):
    with pytest.raises(InputError, match="block must be an integer >= 1"):
        TiledMap(TILE, OVERLAP).build(scans, client=client, block=0)
    with pytest.raises(InputError, match="no scans to build the map from"):
        TiledMap(TILE, OVERLAP).build([], client=client)
    with pytest.raises(InputError, match="got one Scan"):
        TiledMap(TILE, OVERLAP).build(scans[0], client=client)
    with pytest.raises(InputError, match="workers must be an integer >= 1"):
        TiledMap(TILE, OVERLAP).build(scans, workers=0)
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(ImportError, match=r"pip install 'ehm\[tiles\]'"):
        TiledMap(TILE, OVERLAP).build(scans)


def test_peak_memory_is_this_program_s_own():
    """A worker started by a large process reports its own peak, not its parent's."""
    import subprocess

    script = (
        "import numpy as np; from ehm.tiles.build import peak_resident_bytes as peak; "
        "before = peak(); block = np.ones(100_000_000 // 8); print(before, peak())"
    )
    held = np.ones(300_000_000 // 8)  # this process's peak rises past 300 MB
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    before, after = (int(v) for v in result.stdout.split())
    assert before < 250e6 < held.nbytes
    assert after - before > 90e6


def test_a_scheduler_address_runs_the_build_on_that_cluster(client, scans, in_process):
    """As `ehm map --scheduler tcp://host:8786` does: a client of its own on that cluster."""
    tiled = TiledMap(TILE, OVERLAP)
    report = tiled.build(scans, client=client.scheduler.address)
    assert report.workers == 2
    points = probe_points(5000)
    np.testing.assert_array_equal(tiled.occupancy(points), in_process.occupancy(points))


def test_the_index_keeps_up_with_the_tiles_during_a_build(client, scans, tmp_path, monkeypatch):
    """Written as tasks finish (here after each), the index names only tiles on disk, so an
    interrupted build leaves a map that opens."""
    monkeypatch.setattr("ehm.tiles.tiled_map.INDEX_EVERY_SECONDS", 0.0)
    folder = tmp_path / "m.ehm"
    seen = []

    class IndexChecker(Recorder):
        def learning(self, done, total, result):
            if (folder / "index.json").exists():
                partial = ehm.load(folder)
                for key in partial.tile_keys:
                    assert partial.tile(key).n_scans_ == partial.tile_record(key).n_scans
                seen.append(partial.n_tiles)

    tiled = TiledMap(TILE, OVERLAP)
    tiled.build(scans, client=client, directory=folder, block=1, observer=IndexChecker())
    assert seen and min(seen) > 0 and max(seen) < tiled.n_tiles
    assert seen == sorted(seen)
    assert ehm.load(folder).n_tiles == tiled.n_tiles


def test_a_script_without_a_main_guard_is_told_to_add_one(tmp_path):
    # Dask spawns its workers, and each imports the script: a build at the script's top level
    # would run again there. Both the worker and the script name the cure.
    script = tmp_path / "unguarded.py"
    script.write_text(
        "import numpy as np\n"
        "import ehm\n"
        "directions = np.random.default_rng(0).normal(size=(500, 3))\n"
        "directions /= np.linalg.norm(directions, axis=1, keepdims=True)\n"
        "scans = [ehm.Scan(3.0 * directions, np.zeros(3))]\n"
        "ehm.TiledMap(20.0).build(scans, workers=1, directory='city.ehm')\n"
    )
    done = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert done.returncode != 0
    assert "bootstrapping phase" not in done.stderr
    assert "a tiled build started while a worker process imported the script" in done.stderr
    assert done.stderr.rstrip().endswith(
        'put the script\'s code under `if __name__ == "__main__":`'
    )
