"""What changed between two maps of one place: a box that left, a box that arrived, walls that
stayed; as point lists, a picture and `ehm diff`."""

import numpy as np
import pytest
from typer.testing import CliRunner

import ehm
from ehm.cli import app
from ehm.errors import InputError
from ehm.eval.datasets.scene import Scene
from ehm.eval.datasets.simulated import simulate_scan

# A 6 x 4 m room with walls 0.2 m thick; a box that is there on the first day only, and one
# that is there on the second only.
ROOM = [([-3.2, -2.2], [3.2, -2.0]), ([-3.2, 2.0], [3.2, 2.2])]
ROOM += [([-3.2, -2.2], [-3.0, 2.2]), ([3.0, -2.2], [3.2, 2.2])]
LEFT, ARRIVED = ([1.5, 0.8], [2.1, 1.4]), ([-2.0, -1.2], [-1.4, -0.6])
POSES = [[-1.0, 0.0], [0.0, 0.5], [1.0, 0.0], [0.0, -0.5]]


def day_map(boxes, seed: int, hilbert_map=None) -> ehm.HilbertMap | ehm.TiledMap:
    scene = Scene(
        np.array([low for low, _ in boxes]),
        np.array([high for _, high in boxes]),
        np.zeros((0, 2)),
        np.zeros(0),
    )
    angles = np.linspace(0.0, 2.0 * np.pi, 720, endpoint=False)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    rng = np.random.default_rng(seed)
    hilbert_map = ehm.HilbertMap() if hilbert_map is None else hilbert_map
    for pose in POSES:
        hilbert_map.integrate_scan(
            simulate_scan(scene, np.array(pose), directions, 8.0, 0.005, rng)
        )
    return hilbert_map.flush()


@pytest.fixture(scope="module")
def days():
    return day_map([*ROOM, LEFT], 0), day_map([*ROOM, ARRIVED], 1)


def near(points, box, margin=0.15):
    """Whether each of (n, 2) `points` lies within `margin` of `box`, metres: by default as far
    as a hit's sample behind may lie (`occupied_depth`), out past a corner a ray grazed."""
    low, high = np.array(box[0]) - margin, np.array(box[1]) + margin
    return np.all((points >= low) & (points <= high), axis=1)


def read(grid, centres):
    """The grid's probability at the voxels of (n, 2) `centres`."""
    return grid.probability[
        tuple(np.floor((centres - grid.origin) / grid.resolution).astype(int).T)
    ]


def test_what_left_vanished_what_arrived_appeared_and_the_walls_stayed(days):
    old, new = days
    changes = ehm.diff(old, new, resolution=0.05)
    assert changes.dim == 2 and changes.resolution == 0.05
    # Every change lies at one of the two boxes; each box's seen sides are found.
    assert near(changes.vanished, LEFT).all() and near(changes.appeared, ARRIVED).all()
    assert len(changes.vanished) > 30 and len(changes.appeared) > 15
    # Voxel centres of both maps' grids, which read there as the levels say.
    grids = old.grid(changes.bounds, 0.05), new.grid(changes.bounds, 0.05)
    before, after = (read(grid, changes.appeared) for grid in grids)
    assert (before <= changes.free).all() and (after >= changes.occupied).all()
    before, after = (read(grid, changes.vanished) for grid in grids)
    assert (before >= changes.occupied).all() and (after <= changes.free).all()
    # The walls are occupied in both maps, and are no change.
    on_walls = np.zeros(len(changes.stayed), dtype=bool)
    for wall in ROOM:
        on_walls |= near(changes.stayed, wall)
    assert on_walls.mean() > 0.9
    # Nothing changed between a map and itself.
    same = ehm.diff(old, old, resolution=0.05)
    assert len(same.appeared) == len(same.vanished) == 0 and len(same.stayed) > 0


def test_tiled_maps_are_compared_alike(days):
    _, new = days
    tiled = day_map([*ROOM, LEFT], 0, ehm.TiledMap(tile_size=4.0))
    changes = ehm.diff(tiled, new, resolution=0.05)
    assert near(changes.vanished, LEFT).all() and len(changes.vanished) > 30


def test_diff_mistakes_are_named(days):
    old, _ = days
    three_d = ehm.HilbertMap().integrate(np.array([[1.0, 0.0, 0.0]] * 10), np.zeros(3)).flush()
    with pytest.raises(InputError, match="the old map is 2D, the new one 3D"):
        ehm.diff(old, three_d)
    with pytest.raises(InputError, match="levels must be 0 <= free < occupied <= 1"):
        ehm.diff(old, old, occupied=0.3, free=0.4)


def test_ehm_diff_writes_the_picture_and_the_points(days, tmp_path):
    old, new = days
    old.save(tmp_path / "monday.ehm")
    new.save(tmp_path / "tuesday.ehm")
    args = ["diff", str(tmp_path / "monday.ehm"), str(tmp_path / "tuesday.ehm")]
    args += ["-o", str(tmp_path / "changes.png"), "--points", str(tmp_path / "changes.npz")]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "appeared" in result.output and "vanished" in result.output
    assert (tmp_path / "changes.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    points = np.load(tmp_path / "changes.npz")
    expected = ehm.diff(old, new)
    np.testing.assert_array_equal(points["appeared"], expected.appeared)
    np.testing.assert_array_equal(points["vanished"], expected.vanished)
    again = CliRunner().invoke(app, args)
    assert again.exit_code != 0 and "exists" in again.output
