"""`ehm map --tiles` and the commands that read tiled maps, as a user runs them."""

import numpy as np
import pytest
from typer.testing import CliRunner

import ehm
from ehm.cli import app
from ehm.io.readers import read_scans
from ehm.tiles import TiledMap

pytest.importorskip("dask.distributed")
runner = CliRunner(env={"COLUMNS": "240"})


@pytest.fixture(scope="module")
def tiled_plan(tmp_path_factory, plan_log):
    """The floor plan's log mapped in 4 m tiles by two workers, each reading the log."""
    output = tmp_path_factory.mktemp("tiles") / "plan.ehm"
    command = ["map", str(plan_log), "-o", str(output), "--tiles", "4", "--overlap", "1"]
    result = runner.invoke(app, [*command, "--workers", "2"])
    assert result.exit_code == 0, result.output
    assert "5 scans" in result.output and "learned by 2 workers" in result.output
    return output


def test_map_in_tiles_learns_what_one_process_learns(tiled_plan, plan_log, table_row):
    here = TiledMap(4.0, 1.0)
    for scan in read_scans(plan_log):
        here.integrate_scan(scan)
    loaded = ehm.load(tiled_plan)
    points = np.random.default_rng(0).uniform([-8.0, -6.0], [8.0, 6.0], (3000, 2))
    np.testing.assert_array_equal(loaded.occupancy(points), here.occupancy(points))
    info = runner.invoke(app, ["info", str(tiled_plan)])
    assert info.exit_code == 0, info.output
    assert table_row(info.output, "tiles")[0].startswith(f"{here.n_tiles} of 4 m")
    assert table_row(info.output, "scans") == ["5"]
    assert table_row(info.output, "clusters") == [f"{here.n_clusters} in all tiles"]


def test_query_grid_and_render_read_tiled_maps(tiled_plan, tmp_path):
    np.savetxt(tmp_path / "q.csv", [[0.0, 0.0], [2.0, 1.0]], delimiter=",")
    query = runner.invoke(app, ["query", str(tiled_plan), str(tmp_path / "q.csv")])
    assert query.exit_code == 0, query.output
    expected = ehm.load(tiled_plan).occupancy(np.array([[0.0, 0.0], [2.0, 1.0]]))
    assert query.output.split() == [f"{p:.6f}" for p in expected]
    grid = runner.invoke(app, ["grid", str(tiled_plan), "-o", str(tmp_path / "g.npz")])
    assert grid.exit_code == 0, grid.output
    picture = runner.invoke(app, ["render", str(tiled_plan), "-o", str(tmp_path / "p.png")])
    assert picture.exit_code == 0, picture.output


def test_update_adds_scans_to_the_tiles_they_cross(tiled_plan, plan_log, tmp_path):
    copy = tmp_path / "plan.ehm"
    ehm.load(tiled_plan).save(copy)
    result = runner.invoke(
        app, ["map", str(plan_log), "--limit", "1", "-o", str(copy), "--update", "-q"]
    )
    assert result.exit_code == 0, result.output
    assert result.output == ""
    updated = ehm.load(copy)
    assert updated.n_scans_ == 6
    assert max(updated.tile_record(key).version for key in updated.tile_keys) == 2


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--workers", "2"], "--overlap, --workers and --scheduler are for tiled maps"),
        (["--tiles", "4", "--batch"], "--batch and --view are for single maps"),
        (["--tiles", "4", "--update"], "--update adds scans to a map with its own settings"),
        (["--tiles", "0"], "tile size must be a positive number"),
        (["--tiles", "4", "--overlap", "3"], "at most half the tile size"),
    ],
)
def test_bad_tiled_map_options_are_refused(plan_log, tmp_path, extra, message):
    result = runner.invoke(app, ["map", str(plan_log), "-o", str(tmp_path / "m.ehm"), *extra])
    assert result.exit_code == 2
    assert message in result.output
    assert not (tmp_path / "m.ehm").exists() or "--update" in extra


def test_a_tiled_map_is_written_only_where_a_folder_can_be(plan_log, tmp_path, tiled_plan):
    (tmp_path / "file.ehm").write_text("x")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("x")
    cases = [
        (tmp_path / "file.ehm", [], "is a file: a tiled map is written as a folder"),
        (tmp_path / "other", ["--force"], "is a folder of other files"),
        (tiled_plan, [], "exists: --force overwrites it"),
    ]
    for output, extra, message in cases:
        command = ["map", str(plan_log), "-o", str(output), "--tiles", "4", *extra]
        result = runner.invoke(app, command)
        assert result.exit_code == 2 and message in result.output, result.output
