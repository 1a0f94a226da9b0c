import numpy as np
import pytest

import ehm
from ehm.io.map_file import MapFileError


@pytest.fixture(scope="module")
def small_map(plan):
    return ehm.HilbertMap(neighbours=6).fit(plan.scans)


def test_round_trip_answers_exactly_as_saved(small_map, tmp_path, rng):
    path = tmp_path / "plan.ehm"
    small_map.save(path)
    loaded = ehm.load(path)
    points = rng.uniform(-6, 6, (5000, 2))
    np.testing.assert_array_equal(loaded.occupancy(points), small_map.occupancy(points))
    np.testing.assert_array_equal(
        loaded.occupancy(points, mode="exact"), small_map.occupancy(points, mode="exact")
    )
    assert loaded.config == small_map.config
    assert loaded.n_scans_ == small_map.n_scans_
    assert loaded.memory_bytes() == small_map.memory_bytes()
    # Saving the loaded map again gives the same bytes.
    loaded.save(tmp_path / "again.ehm")
    assert (tmp_path / "again.ehm").read_bytes() == path.read_bytes()


def test_memory_bytes_counts_every_array(small_map):
    arrays = small_map.clusters_.arrays().values()
    assert small_map.memory_bytes() > sum(a.nbytes for a in arrays)
    assert small_map.memory_bytes() < 3 * sum(a.nbytes for a in arrays)


def test_loaded_map_keeps_learning(small_map, plan, tmp_path):
    small_map.save(tmp_path / "m.ehm")
    loaded = ehm.load(tmp_path / "m.ehm")
    loaded.integrate_scan(plan.scans[0])
    assert loaded.n_scans_ == small_map.n_scans_ + 1


def test_corrupt_truncated_and_foreign_files_are_refused(small_map, tmp_path):
    path = tmp_path / "m.ehm"
    small_map.save(path)
    data = path.read_bytes()
    flipped = bytearray(data)
    flipped[len(data) // 2] ^= 0xFF
    cases = {
        "corrupt": bytes(flipped),
        "truncated": data[: len(data) - 100],
        "not an ehm map file": b"PK\x03\x04 a zip file, not a map",
        "newer than this ehm reads": data[:8] + (99).to_bytes(4, "little") + data[12:],
        "older than this ehm reads": data[:8] + (1).to_bytes(4, "little") + data[12:],
    }
    for message, content in cases.items():
        bad = tmp_path / "bad.ehm"
        bad.write_bytes(content)
        with pytest.raises(MapFileError, match=message):
            ehm.load(bad)


def test_save_is_atomic(small_map, tmp_path, monkeypatch):
    path = tmp_path / "m.ehm"
    small_map.save(path)
    before = path.read_bytes()

    def crash(*args):
        raise OSError("disk full")

    monkeypatch.setattr("os.replace", crash)
    with pytest.raises(OSError, match="disk full"):
        small_map.save(path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.ehm"]


def test_empty_map_cannot_be_saved(tmp_path):
    with pytest.raises(ValueError, match="the map is empty"):
        ehm.HilbertMap().save(tmp_path / "x.ehm")
