"""The map folder's index: written whole, read back, and refused by name when it is bad."""

import pytest

from ehm.errors import FileReadError
from ehm.tiles.store import TileIndex, TileIndexError, TileRecord, TileStore


def test_the_index_round_trips(tmp_path):
    index = TileIndex(
        25.0,
        4.8,
        3,
        {"cluster_radius": 0.48},
        2,
        [[0.0, 0.0, 1.8], [1.0, 0.0, 1.8]],
        {
            (0, -1, 0): TileRecord(2, 2, 10, 1234, [[0.0, -37.0, -12.0], [12.0, -12.0, 8.0]]),
            (1, 0, 0): TileRecord(1, 1, 0, 99, []),
        },
    )
    store = TileStore(tmp_path / "m.ehm")
    store.prepare()
    store.write_index(index)
    assert TileStore.holds_map(tmp_path / "m.ehm")
    assert store.read_index() == index
    assert store.tile_path((0, -1, 0)).name == "0_-1_0.ehm"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", "not JSON"),
        ('{"format": "something else"}', "not the index of a tiled ehm map"),
        ('{"format": "ehm tiled map", "version": 99}', "newer than this ehm reads"),
        ('{"format": "ehm tiled map", "version": 1, "tiles": []}', "inconsistent index"),
    ],
)
def test_bad_indexes_are_refused_by_name(tmp_path, text, message):
    (tmp_path / "index.json").write_text(text)
    with pytest.raises(TileIndexError, match=message) as error:
        TileStore(tmp_path).read_index()
    assert isinstance(error.value, FileReadError)
    assert "index.json" in str(error.value)


def test_a_missing_tile_is_named(tmp_path):
    with pytest.raises(FileReadError, match=r"tile \(1, 2\) of the index cannot be read"):
        TileStore(tmp_path).read_tile((1, 2))
