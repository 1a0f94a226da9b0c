"""The browser viewer's server: the scene it serves and what its controls do."""

import socket

import numpy as np
import pytest

import ehm

viser = pytest.importorskip("viser")
from ehm.viz.viewer import MapViewer  # noqa: E402


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture
def room_viewer(room_map):
    viewer = MapViewer(room_map, resolution=0.1, port=free_port())
    yield viewer
    viewer.server.stop()


def test_the_level_slider_remeshes_the_surface(room_viewer):
    before = room_viewer.n_faces
    vertices = np.asarray(room_viewer.mesh.vertices)
    assert before > 10_000
    # At the level, to the grid's interpolation and its difference from point queries.
    assert np.median(np.abs(room_viewer.map.occupancy(vertices[::100]) - 0.5)) < 0.1
    room_viewer.level.value = 0.8  # as a client moving the slider
    assert 0 < room_viewer.n_faces != before
    higher = np.asarray(room_viewer.mesh.vertices)
    assert np.median(room_viewer.map.occupancy(higher[::100])) > 0.6


def test_colouring_by_uncertainty_and_the_slice(room_viewer):
    by_height = np.asarray(room_viewer.mesh.visual.vertex_colors).copy()
    room_viewer.coloring.value = "uncertainty (std)"
    by_std = np.asarray(room_viewer.mesh.visual.vertex_colors)
    assert by_std.shape == by_height.shape and not np.array_equal(by_std, by_height)
    room_viewer.show_slice.value = True
    room_viewer.slice_height.value = 1.0
    room_viewer.slice_of.value = "uncertainty (std)"
    assert not room_viewer.samples.visible
    room_viewer.show_samples.value = True
    assert room_viewer.samples.visible
    assert room_viewer.url.startswith("http://127.0.0.1:")


def test_the_slice_of_distances_to_obstacles(room_viewer):
    room_viewer.show_slice.value = True
    room_viewer.slice_height.value = 1.2
    room_viewer.slice_of.value = "distance to obstacles"
    image = room_viewer.slice_image.astype(int)
    grid = room_viewer.grid

    def pixel(x, y):
        return np.argmin(np.abs(grid.axis_centers(0) - x)), np.argmin(
            np.abs(grid.axis_centers(1) - y)
        )

    # The room's middle, over a metre from every wall: blue; inside a wall (x = 4 to 4.2 m),
    # a few centimetres deep: red.
    red, _, blue = image[pixel(0.0, 0.0)]
    assert blue > red + 80
    red, _, blue = image[pixel(4.1, 0.0)]
    assert red > blue + 40
    room_viewer.show_slice.value = False
    assert room_viewer.slice_image is None


def test_a_plan_shows_as_an_image(plan):
    plan_map = ehm.HilbertMap().fit(plan.scans)
    viewer = MapViewer(plan_map, resolution=0.1, port=free_port())
    try:
        assert viewer.surface is None and len(plan_map.sensor_path) == len(plan.scans)
    finally:
        viewer.server.stop()


def test_ehm_view_names_its_mistakes(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from ehm.cli import app

    result = CliRunner().invoke(app, ["view", str(tmp_path / "none.ehm")])
    assert result.exit_code == 2 and "none.ehm: no such file" in result.stderr
    result = CliRunner().invoke(app, ["view", str(tmp_path / "none.ehm"), "--port", "0"])
    assert result.exit_code == 2 and "--port must be 1 to 65535, got 0" in result.stderr
    monkeypatch.setitem(__import__("sys").modules, "viser", None)  # as if not installed
    (tmp_path / "m.ehm").write_bytes(b"")
    result = CliRunner().invoke(app, ["view", str(tmp_path / "m.ehm")])
    assert result.exit_code == 2 and "pip install 'ehm[viewer]'" in result.stderr


@pytest.mark.parametrize("scans", ["plan", "room"])
def test_a_live_view_shows_the_map_as_it_grows(request, scans):
    from ehm.pipeline import MappingPipeline
    from ehm.viz.viewer import LiveView

    data = request.getfixturevalue(scans)
    live = LiveView(port=free_port(), refresh_seconds=0.0)
    try:
        hilbert_map = ehm.HilbertMap(batch_rays=0)
        run = MappingPipeline(data.scans, hilbert_map, observers=[live]).run()
        # Every learned scan, and once more at the end.
        assert live.refreshes == run.n_scans + 1
        assert f"**{run.n_scans} scans**" in live.readout
    finally:
        live.server.stop()


def test_cutting_above_a_height_leaves_out_the_ceiling(room_viewer):
    whole = room_viewer.n_faces
    room_viewer.cut_above.value = 2.0
    vertices = np.asarray(room_viewer.mesh.vertices)
    faces = np.asarray(room_viewer.mesh.faces)
    assert 0 < room_viewer.n_faces < whole
    assert np.all(vertices[faces, 2].min(axis=1) <= 2.0)


def test_the_sliders_open_on_round_heights_below_the_ceiling(room_viewer, room_map):
    step = room_viewer.grid.resolution
    sensor = float(np.median(room_map.sensor_path[:, 2]))
    for slider in (room_viewer.slice_height, room_viewer.cut_above):
        for value in (slider.min, slider.max, slider.value):
            assert abs(value / step - round(value / step)) < 1e-9
            assert value == round(value, 6)  # shown as 1.2, not 1.2000000000000002
    assert room_viewer.slice_height.value == pytest.approx(sensor, abs=step / 2)
    assert room_viewer.cut_above.value == pytest.approx(sensor + 1.0, abs=step / 2)
    assert room_viewer.cut_above.value < 3.0 < room_viewer.cut_above.max  # under the ceiling
