"""The command line, as a user runs it."""

import re

import numpy as np
import pytest
from typer.testing import CliRunner

import ehm
from ehm.cli import app
from ehm.cli.app import parse_settings
from ehm.config import MapConfig
from ehm.errors import InputError
from ehm.eval.runner import RECORD_KEYS
from ehm.io.distance_file import load_distance_grid
from ehm.io.grid_file import load_grid
from ehm.io.ply import read_ply

runner = CliRunner(env={"COLUMNS": "240"})


@pytest.fixture(scope="module")
def map_file(tmp_path_factory, plan_log):
    output = tmp_path_factory.mktemp("cli") / "plan.ehm"
    result = runner.invoke(app, ["map", str(plan_log), "-o", str(output), "--set", "neighbours=6"])
    assert result.exit_code == 0, result.output
    assert "5 scans" in result.output and "sgd" in result.output
    return output


@pytest.fixture(scope="module")
def room_map_file(tmp_path_factory, room):
    path = tmp_path_factory.mktemp("room") / "room.ehm"
    ehm.HilbertMap().fit(room.scans).save(path)
    return path


def test_map_then_info_and_query(map_file, tmp_path, table_row):
    hilbert_map = ehm.load(map_file)
    info = runner.invoke(app, ["info", str(map_file)])
    assert info.exit_code == 0, info.output
    assert table_row(info.output, "kernels.neighbours") == ["6"]  # set when it was made
    assert "kernels.coarse_neighbours" not in info.output  # at its default: --all shows it
    assert table_row(info.output, "other settings") == ["60 at their defaults for 0.05 m (--all)"]
    every = runner.invoke(app, ["info", str(map_file), "--all"]).output
    assert table_row(every, "kernels.coarse_neighbours") == ["4"]
    assert table_row(info.output, "dimensions") == ["2"]
    assert table_row(info.output, "scans") == ["5"]
    assert table_row(info.output, "log-odds read times") == ["1 (raw: calibrate is off)"]
    path = hilbert_map.sensor_path
    length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert table_row(info.output, "sensor path") == [f"5 poses, {length:.2f} m long"]
    assert table_row(info.output, "clusters") == [str(hilbert_map.n_clusters)]
    assert table_row(info.output, "memory") == [f"{hilbert_map.memory_bytes() / 1e6:.3f} MB"]
    kept = hilbert_map.model_.memory
    assert len(kept) > 0
    assert table_row(info.output, "past evidence kept") == [
        f"{len(kept)} cells, {kept.weight.sum():.0f} samples"
    ]
    points = np.array([[-3.0, -1.5], [6.0, -0.2]])
    np.save(tmp_path / "q.npy", points)
    np.savetxt(tmp_path / "q.csv", points, delimiter=",")
    expected = hilbert_map.occupancy(points)
    out = runner.invoke(app, ["query", str(map_file), str(tmp_path / "q.csv")])
    assert out.exit_code == 0, out.output
    np.testing.assert_allclose(np.array(out.output.split(), float), expected, atol=1e-6)
    result = runner.invoke(
        app, ["query", str(map_file), str(tmp_path / "q.npy"), "-o", str(tmp_path / "p.npy")]
    )
    assert result.exit_code == 0, result.output
    np.testing.assert_array_equal(np.load(tmp_path / "p.npy"), expected)
    assert expected[0] < 0.5 < expected[1]  # a robot pose is free, the wall occupied
    with_std = np.column_stack(hilbert_map.occupancy(points, return_std=True))
    out = runner.invoke(app, ["query", str(map_file), str(tmp_path / "q.csv"), "--std"])
    assert out.exit_code == 0, out.output
    rows = [line.split(",") for line in out.output.split()]
    np.testing.assert_allclose(np.array(rows, float), with_std, atol=1e-6)
    result = runner.invoke(
        app,
        ["query", str(map_file), str(tmp_path / "q.npy"), "--std", "-o", str(tmp_path / "s.csv")],
    )
    assert result.exit_code == 0, result.output
    np.testing.assert_allclose(np.loadtxt(tmp_path / "s.csv", delimiter=","), with_std, atol=1e-6)


def test_bad_inputs_give_clear_errors(map_file, plan_log, tmp_path):
    def fails(args: list[str], code: int, message: str) -> None:
        result = runner.invoke(app, args)
        assert result.exit_code == code, result.output
        assert message in " ".join(result.output.split()), result.output

    (tmp_path / "junk.ehm").write_bytes(b"junk")
    fails(["info", str(tmp_path / "junk.ehm")], 2, "not an ehm map file (unknown magic bytes)")
    np.save(tmp_path / "q3.npy", np.zeros((2, 3)))
    fails(
        ["query", str(map_file), str(tmp_path / "q3.npy")],
        2,
        "q3.npy: expected points of shape (n, 2), got float64 (2, 3)",
    )
    output = str(tmp_path / "x.ehm")
    fails(["map", str(tmp_path / "nothing.ply"), "-o", output], 2, "nothing.ply: no such file")
    log = str(plan_log)
    fails(["map", log, "-o", output, "--set", "k=1"], 2, "'k=1': expected name=value with a")
    fails(["map", log, "-o", output, "--set", "neighbours"], 2, "expected name=value")
    fails(["map", log, "-o", output, "--set", "neighbours=0"], 2, "must be an integer >= 1")
    fails(["map", log, "-o", output, "--set", "neighbours=1.5"], 2, "neighbours is an int, got")
    fails(["map", log, "-o", output, "--set", "planar_kernel=maybe"], 2, "is true or false")
    fails(["map", log, "-o", output, "--set", "l2=nan"], 2, "l2 must be a finite number")
    fails(["map", log, "-o", output, "--origin", "a,b,c"], 2, "--origin: could not convert")
    fails(["map", log, "-o", output, "--origin", "0,nan,1"], 2, "finite numbers, got '0,nan,1'")
    fails(["map", log, "-o", output, "--set", "cluster_radius=inf"], 2, "must be a finite")
    fails(["map", log, "-o", output, "--set", "forget_after=soon"], 2, "is a float, got 'soon'")
    fails(["map", log, "-o", output, "--set", "forget_after=-1"], 2, "a positive number of sec")
    fails(["map", log, "-o", output, "--resolution", "0"], 2, "resolution must be a positive")
    assert not (tmp_path / "x.ehm").exists()


def test_map_help_names_every_reader():
    from ehm.io.readers import FORMATS

    result = runner.invoke(app, ["map", "--help"], env={"COLUMNS": "400"})
    assert " ".join(FORMATS) in " ".join(result.output.split())


def test_help_shows_flags_bare_and_summaries_as_flowing_text():
    wide = {"COLUMNS": "400"}
    group_help = runner.invoke(app, ["--help"], env=wide).output
    # One line a command at this width: the docstring's own line breaks are gone.
    assert (
        "demo    Simulate the virtual room, map it, score the map against the exact "
        "occupancy, and write the map" in group_help
    )
    for command in ["demo", "map", "query", "grid", "mesh", "render", "export", "view"]:
        output = runner.invoke(app, [command, "--help"], env=wide).output
        assert "<bool>" not in output, command
        assert "{map_path}" not in output and "{inputs}" not in output, command
    usage = runner.invoke(app, ["query", "--help"], env=wide).output
    assert "query [OPTIONS] {MAP} {POINTS}" in usage


def test_version_is_told_and_stops():
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output == f"ehm {ehm.__version__}\n"


def test_settings_that_may_be_off_take_none():
    settings = parse_settings(["replay_cap=none", "forget_after=30"])
    assert settings == {"replay_cap": None, "forget_after": 30.0}
    assert ehm.MapConfig(**settings).replay_cap is None
    with pytest.raises(InputError, match="learning_rate is a float, got 'none'"):
        parse_settings(["learning_rate=none"])
    # Off by default or not, a setting takes a value of its declared type.
    assert ehm.MapConfig.setting_type("forget_after") is float
    assert ehm.MapConfig.setting_type("min_hit_cluster_size") is int
    assert parse_settings(["min_hit_cluster_size=2"]) == {"min_hit_cluster_size": 2}
    with pytest.raises(InputError, match=r"min_hit_cluster_size is an int, got '2\.5'"):
        parse_settings(["min_hit_cluster_size=2.5"])


def test_a_log_with_time_stamps_makes_a_map_that_fades(plan_log, tmp_path):
    output = tmp_path / "fading.ehm"
    result = runner.invoke(
        app, ["map", str(plan_log), "-o", str(output), "--set", "forget_after=600"]
    )
    assert result.exit_code == 0, result.output
    loaded = ehm.load(output)
    assert loaded.config.forget_after == 600.0 and loaded.time_ == 0.0  # the log's stamps


def test_map_at_another_resolution_scales_its_settings(plan_log, tmp_path, table_row):
    log, output = str(plan_log), tmp_path / "coarse.ehm"
    result = runner.invoke(
        app, ["map", log, "-o", str(output), "--resolution", "0.1", "--set", "min_std=0.03"]
    )
    assert result.exit_code == 0, result.output
    config = ehm.load(output).config
    assert config.cluster_radius == pytest.approx(0.24) and config.min_std == 0.03
    # The map keeps its resolution, and its outputs default to it.
    info = runner.invoke(app, ["info", str(output)])
    assert "resolution" in info.output and "0.1 m (outputs default to it)" in info.output
    # Only the setting given differs from the defaults at 0.1 m.
    assert table_row(info.output, "kernels.min_std") == ["0.03"]
    assert "clustering.cluster_radius" not in info.output
    grid_path = tmp_path / "coarse.npz"
    result = runner.invoke(app, ["grid", str(output), "-o", str(grid_path)])
    assert result.exit_code == 0, result.output
    assert load_grid(grid_path).resolution == pytest.approx(0.1)


def test_demo_writes_map_mesh_and_pictures(tmp_path):
    result = runner.invoke(app, ["demo", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    # Kernels are compiled or loaded before anything is timed, and the demo says which.
    assert re.search(
        r"(compiled the kernels in \d+ s|loaded the compiled kernels in)", result.output
    )
    assert "ROC-AUC" in result.output and "near surfaces" in result.output
    assert (tmp_path / "virtual_room_slices.png").stat().st_size > 10_000
    assert (tmp_path / "virtual_room_mesh.png").stat().st_size > 10_000
    room_map = ehm.load(tmp_path / "virtual_room.ehm")
    assert room_map.dim == 3
    vertices = read_ply(tmp_path / "virtual_room.ply")
    # Mesh vertices sit where the map reads 0.5, well inside the room's walls.
    assert len(vertices) > 10_000
    assert np.all(np.abs(vertices[:, :2]) < [4.5 + 2.0, 3.5 + 2.0])
    assert np.median(np.abs(room_map.occupancy(vertices) - 0.5)) < 0.05


def test_grid_mesh_and_render_commands(room_map_file, map_file, tmp_path):
    bounds = "-4.2,-3.2,-0.2,4.2,3.2,2.5"
    result = runner.invoke(
        app,
        ["grid", str(room_map_file), "-o", str(tmp_path / "g.npz"), "--resolution", "0.1", "--std"],
    )
    assert result.exit_code == 0, result.output
    grid = load_grid(tmp_path / "g.npz")
    assert grid.resolution == 0.1 and grid.dim == 3
    expected = ehm.load(room_map_file).grid(resolution=0.1, std=True)
    np.testing.assert_array_equal(grid.std, expected.std)
    ply = tmp_path / "room.ply"
    result = runner.invoke(app, ["mesh", str(room_map_file), "-o", str(ply), "--bounds", bounds])
    assert result.exit_code == 0, result.output
    vertices = read_ply(ply)
    assert np.all(vertices >= [-4.2, -3.2, -0.2]) and np.all(vertices <= [4.2, 3.2, 2.5])
    picture = tmp_path / "room.png"
    result = runner.invoke(
        app,
        [
            "render",
            str(room_map_file),
            "-o",
            str(picture),
            "--cut-above",
            "2.0",
            "--resolution",
            "0.1",
            "--slices",
            str(tmp_path / "slices.png"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert picture.stat().st_size > 10_000 and (tmp_path / "slices.png").exists()
    # 2D maps: a picture and a grid, no mesh; the std as a picture of the plane
    std_picture = tmp_path / "plan_std.png"
    result = runner.invoke(
        app, ["render", str(map_file), "-o", str(tmp_path / "plan.png"), "--std", str(std_picture)]
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "plan.png").stat().st_size > 10_000
    assert std_picture.stat().st_size > 10_000 and str(std_picture) in result.output
    result = runner.invoke(app, ["mesh", str(map_file), "-o", str(tmp_path / "plan.ply")])
    assert result.exit_code != 0 and "no surface mesh" in result.output


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--resolution", "0"], "resolution must be a positive"),
        (["--bounds", "0,0,0,1,1"], "--bounds: 6 numbers for a 3D map, got 5"),
        (["--bounds", "0,0,0,1,-1,1"], "inverted"),
        (["--resolution", "0.001", "--max-gib", "0.5"], "more than the limit of 0.50 GiB"),
    ],
)
def test_bad_grid_options_give_clear_errors(room_map_file, tmp_path, options, message):
    result = runner.invoke(
        app, ["mesh", str(room_map_file), "-o", str(tmp_path / "m.ply"), *options]
    )
    assert result.exit_code != 0 and message in " ".join(result.output.split()), result.output


def test_eval_writes_records_with_the_protocol_keys_and_plots(tmp_path, room):
    import json

    out, plots = tmp_path / "records.json", tmp_path / "plots"
    args = ["eval", "--methods", "ehm,ehm-batch", "--fractions", "0.8,0.5", "--seeds", "0,1"]
    result = runner.invoke(app, [*args, "--json", str(out), "--plots", str(plots)])
    assert result.exit_code == 0, result.output
    assert "virtual_room: held-out rays, mean±std over 2 seeds" in result.output
    assert "ehm-batch: EHM, single batch" in result.output
    records = json.loads(out.read_text())
    assert len(records) == 2 * 2 * 2
    expected = {
        "dataset", "method", "fraction", "seed", "accuracy", "f1", "auc", "unknown",
        "build_s", "query_s", "memory_bytes", "n_train", "n_test",
    }  # fmt: skip
    assert set(RECORD_KEYS) == expected
    for record in records:
        assert set(record) == expected
        assert record["dataset"] == "virtual_room"
        assert 0.5 < record["auc"] <= 1.0 and 0.0 <= record["unknown"] <= 1.0
        assert abs(record["n_train"] / len(room.scans[0]) - record["fraction"]) < 0.01
    assert {(r["method"], r["fraction"], r["seed"]) for r in records} == {
        (m, f, s) for m in ("ehm", "ehm-batch") for f in (0.8, 0.5) for s in (0, 1)
    }
    for name in ("sparsity_virtual_room.png", "cost_virtual_room.png"):
        assert (plots / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_eval_names_bad_options(monkeypatch, tmp_path):
    result = runner.invoke(app, ["eval", "--methods", "ehm,voxblox"])
    assert result.exit_code == 2 and "unknown method 'voxblox'" in result.output
    result = runner.invoke(app, ["eval", "--datasets", "kitti"])
    assert result.exit_code == 2 and "unknown data set(s) kitti" in result.output
    result = runner.invoke(app, ["eval", "--fractions", "0.8,1.2"])
    assert result.exit_code == 2 and "must be in (0, 1), got 1.2" in result.output
    monkeypatch.setenv("EHM_DATA_DIR", str(tmp_path))
    result = runner.invoke(app, ["eval", "--methods", "ehm", "--datasets", "intel_lab"])
    assert result.exit_code == 2
    assert "skipped intel_lab" in result.output and "nothing to evaluate" in result.output


def test_export_writes_each_format(room_map_file, map_file, tmp_path):
    octomap = pytest.importorskip("octomap")
    bounds = ["--bounds", "-2,-2,0,2,2,2.6", "--resolution", "0.1"]
    for name in ("room.bt", "room.ot", "room.ply", "room.pcd"):
        result = runner.invoke(
            app, ["export", str(room_map_file), "-o", str(tmp_path / name), *bounds]
        )
        assert result.exit_code == 0, result.output
    tree = octomap.OcTree(0.1)
    assert tree.readBinary(str(tmp_path / "room.bt").encode()) and tree.getNumLeafNodes() > 1000
    assert len(read_ply(tmp_path / "room.ply")) > 1000
    result = runner.invoke(app, ["export", str(map_file), "-o", str(tmp_path / "plan.pgm")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "plan.yaml").read_text().startswith("image: plan.pgm\n")
    assert re.search(r"\d+ x \d+ cells of 0.05 m: free \d+%, occupied \d+%", result.output)
    result = runner.invoke(app, ["export", str(map_file), "-o", str(tmp_path / "plan.bt")])
    assert result.exit_code == 2 and "OctoMap trees are 3D" in result.stderr
    result = runner.invoke(app, ["export", str(room_map_file), "-o", str(tmp_path / "r.pgm")])
    assert result.exit_code == 0, result.output
    assert re.search(r"note: projected heights 0\.[2-4]\d to 2\.[0-2]\d m", result.stderr)
    heights = ["--z-min", "0.5", "--z-max", "1.5"]
    result = runner.invoke(
        app, ["export", str(room_map_file), "-o", str(tmp_path / "band.pgm"), *heights]
    )
    assert result.exit_code == 0 and "note:" not in result.stderr, result.output
    result = runner.invoke(
        app, ["export", str(room_map_file), "-o", str(tmp_path / "r.bt"), *heights]
    )
    assert result.exit_code == 2 and "heights a .pgm export projects" in result.stderr
    result = runner.invoke(
        app, ["export", str(map_file), "-o", str(tmp_path / "flat.pgm"), *heights]
    )
    assert result.exit_code == 2 and "this map is 2D" in result.stderr
    result = runner.invoke(app, ["export", str(room_map_file), "-o", str(tmp_path / "r.obj")])
    assert result.exit_code == 2 and "expected a name ending in .ot, .bt, .pgm" in result.stderr
    result = runner.invoke(app, ["export", str(map_file), "-o", str(tmp_path / "plan.pgm")])
    assert result.exit_code == 2 and "plan.pgm exists: --force overwrites it" in result.stderr


def test_a_georeferenced_map_exports_its_tree_around_its_local_origin(room, tmp_path):
    octomap = pytest.importorskip("octomap")
    shift = np.array([499_712.0, 4_199_424.0, 2048.0])
    path = tmp_path / "utm.ehm"
    scan = room.scans[0]
    ehm.HilbertMap().integrate(scan.points_world + shift, scan.origin + shift).save(path)
    result = runner.invoke(app, ["export", str(path), "-o", str(tmp_path / "utm.bt")])
    assert result.exit_code == 0, result.output
    assert "note: the tree is written relative to [499712.0, 4199424.0, 2048.0] m" in (
        " ".join(result.stderr.split())
    )
    tree = octomap.OcTree(0.05)
    assert tree.readBinary(str(tmp_path / "utm.bt").encode())
    low, high = tree.getMetricMin(), tree.getMetricMax()
    assert np.all(low > [-6, -5, -2]) and np.all(high < [6, 5, 5])  # the room, near 0


def test_query_tells_distances_to_obstacles(map_file, tmp_path):
    points = np.array([[-3.0, -1.5], [1.5, -0.2], [6.0, -0.2]])
    np.save(tmp_path / "q.npy", points)
    hilbert_map = ehm.load(map_file)
    expected = np.column_stack(
        [*hilbert_map.occupancy(points, return_std=True), hilbert_map.distance(points)]
    )
    args = ["query", str(map_file), str(tmp_path / "q.npy"), "--std", "--distance"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    rows = [line.split(",") for line in result.output.split()]
    np.testing.assert_allclose(np.array(rows, float), expected, atol=1e-6)
    assert expected[0, 2] > 0.3 and expected[2, 2] < 0.0  # a robot pose, inside the wall


def test_export_writes_a_distance_field(map_file, tmp_path):
    output = tmp_path / "field.npz"
    args = ["export", str(map_file), "-o", str(output), "--distance", "--resolution", "0.1"]
    args += ["--bounds", "-4.95,-3.45,4.95,3.45"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "100 x 70 voxels of 0.1 m" in result.output
    field = load_distance_grid(output)
    assert field.distance.shape == (100, 70) and field.gradient.shape == (100, 70, 2)
    np.testing.assert_allclose(field.origin, [-5.0, -3.5])
    centres = np.array([[-4.95 + 0.1 * i, -3.45 + 0.1 * j] for i, j in [(20, 20), (70, 30)]])
    expected, slope = ehm.load(map_file).distance(centres, return_gradient=True)
    np.testing.assert_allclose(field.distance[[20, 70], [20, 30]], expected, atol=1e-12)
    np.testing.assert_allclose(field.gradient[[20, 70], [20, 30]], slope, atol=1e-12)
    assert field.level == 0.5 and field.unknown_is_occupied
    assert field.distance.min() < 0.0 < field.distance.max()  # walls and the rooms between
    result = runner.invoke(app, [*args, "--unknown", "free", "--force"])
    assert result.exit_code == 0, result.output
    free = load_distance_grid(output)
    # Without unknown space as an obstacle, distances grow or stay (but for the field's own
    # error, a voxel or two where surfels are placed differently).
    assert not free.unknown_is_occupied
    assert np.mean(free.distance > field.distance + 0.1) > 0.05
    assert np.mean(free.distance < field.distance - 0.1) < 0.01
    result = runner.invoke(app, ["export", str(map_file), "-o", str(tmp_path / "f.npz")])
    assert result.exit_code == 2 and "--distance writes .npz files" in result.stderr
    args = ["export", str(map_file), "-o", str(tmp_path / "f.pgm"), "--unknown", "free"]
    result = runner.invoke(app, args)
    assert result.exit_code == 2 and "--unknown goes with --distance" in result.stderr
    result = runner.invoke(app, [*args[:4], "-o", str(output), "--distance", "--unknown", "yes"])
    assert (
        result.exit_code == 2 and "--unknown must be occupied or free, got 'yes'" in result.stderr
    )


def test_a_long_range_capture_maps_with_notes_of_its_decoder_and_resolution(tmp_path):
    from ouster_captures import ouster_metadata, write_ouster

    metadata = ouster_metadata(np.linspace(-5.0, 5.0, 16), 512, "RNG19_RFL8_SIG16_NIR16", 16)
    ranges = np.full((1, 16, 512), 60_000)  # a ring of wall 60 m away
    capture = write_ouster(tmp_path / "far.pcap", metadata, ranges)
    output = tmp_path / "far.ehm"
    result = runner.invoke(app, ["map", str(capture), "-o", str(output), "--quiet"])
    assert result.exit_code == 0, result.output
    assert "note: far.pcap: decoded with far.json (RNG19_RFL8_SIG16_NIR16, 16 x 512)" in (
        " ".join(result.stderr.split())
    )
    assert re.search(r"note: the map reaches 6\d m from the sensor at 0\.05 m", result.stderr)
    result = runner.invoke(
        app, ["map", str(capture), "-o", str(output), "--quiet", "--force", "--resolution", "0.2"]
    )
    assert result.exit_code == 0 and "reaches" not in result.stderr, result.output


def test_ctrl_c_stops_after_the_scan_at_hand_and_saves_the_map(plan_log, tmp_path, monkeypatch):
    import os
    import signal

    from ehm.io.readers import ScanFiles

    read = ScanFiles.__iter__

    def interrupted_after_two(files):
        for index, scan in enumerate(read(files)):
            if index == 2:
                os.kill(os.getpid(), signal.SIGINT)  # as Ctrl-C does, while scan 2 is read
            yield scan

    monkeypatch.setattr(ScanFiles, "__iter__", interrupted_after_two)
    handler = signal.getsignal(signal.SIGINT)  # ignored in a shell's background job
    output = tmp_path / "stopped.ehm"
    result = runner.invoke(app, ["map", str(plan_log), "-o", str(output), "--quiet"])
    assert result.exit_code == 130, result.output
    assert "stopped by Ctrl-C after 2 scans; the map of those is saved" in result.stderr
    assert ehm.load(output).n_scans_ == 2
    assert signal.getsignal(signal.SIGINT) is handler


def test_map_takes_every_nth_scan_up_to_a_limit_quietly(plan_log, tmp_path):
    output = tmp_path / "some.ehm"
    args = ["map", str(plan_log), "-o", str(output), "--every", "2", "--limit", "2", "--quiet"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert result.output == ""
    assert ehm.load(output).n_scans_ == 2  # scans 0 and 2 of 5
    result = runner.invoke(
        app, ["map", str(plan_log), "-o", str(tmp_path / "x.ehm"), "--every", "0"]
    )
    assert result.exit_code == 2 and "every must be an integer >= 1, got 0" in result.stderr


def test_demo_data_writes_the_guides_recordings_once(tmp_path):
    folder = tmp_path / "guides"
    result = runner.invoke(app, ["demo", "--data", str(folder)])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in folder.iterdir()) == ["floor.log", "kitti", "room.bag", "tum_fr2"]
    assert len((folder / "floor.log").read_text().splitlines()) == 5  # five FLASER scans
    assert len(list((folder / "kitti" / "sequences" / "00" / "velodyne").iterdir())) == 3
    again = runner.invoke(app, ["demo", "--data", str(folder)])
    assert again.exit_code == 2
    assert "already holds floor.log, tum_fr2, kitti, room.bag: give a new or empty" in again.output


def test_the_log_file_holds_each_scan_the_notes_and_errors(tmp_path, plan_log):
    log = tmp_path / "ehm.log"
    result = runner.invoke(app, ["--log", str(log), "map", str(plan_log), "-o",
                                 str(tmp_path / "a.ehm"), "-q"])  # fmt: skip
    assert result.exit_code == 0, result.output
    failed = runner.invoke(app, ["--log", str(log), "map", str(tmp_path / "none.log"), "-o",
                                 str(tmp_path / "b.ehm")])  # fmt: skip
    assert failed.exit_code == 2
    lines = log.read_text().splitlines()
    scans = [line for line in lines if " INFO ehm.pipeline: scan " in line]
    assert len(scans) == 5 and scans[0].split(" INFO ")[1].startswith("ehm.pipeline: scan 0: ")
    assert any(" INFO ehm.pipeline: mapped 5 scans, " in line for line in lines)
    missing = f"ERROR ehm.cli: error: {tmp_path / 'none.log'}: no such file or folder"
    assert lines[-1].endswith(missing)
    assert "scan 0" not in result.output  # the file only, without -v


def test_verbose_logs_each_scan_on_stderr(tmp_path, plan_log):
    result = runner.invoke(app, ["-v", "map", str(plan_log), "-o", str(tmp_path / "a.ehm"), "-q"])
    assert result.exit_code == 0
    assert "scan 4: 180 rays in" in " ".join(result.output.split())
    unwritable = runner.invoke(app, ["--log", str(tmp_path), "info", str(tmp_path / "a.ehm")])
    assert unwritable.exit_code == 2 and f"--log {tmp_path}: Is a directory" in unwritable.output


def test_a_map_keeps_its_settings_beside_it_and_config_reads_them(tmp_path, plan_log):
    first = tmp_path / "first.ehm"
    made = runner.invoke(app, ["map", str(plan_log), "-o", str(first), "-q", "--resolution",
                               "0.1", "--set", "neighbours=6"])  # fmt: skip
    assert made.exit_code == 0, made.output
    settings = tmp_path / "first.settings.toml"
    assert "[kernels]" in settings.read_text()
    again = tmp_path / "again.ehm"
    result = runner.invoke(app, ["map", str(plan_log), "-o", str(again), "-q", "--config",
                                 str(settings), "--set", "epochs=3"])  # fmt: skip
    assert result.exit_code == 0, result.output
    expected = MapConfig.for_resolution(0.1, neighbours=6, epochs=3)
    assert ehm.load(again).config == expected
    assert MapConfig.from_toml((tmp_path / "again.settings.toml").read_text()) == expected
    bad = tmp_path / "bad.toml"
    bad.write_text("[queries]\nepochs = 3\n")
    refused = runner.invoke(app, ["map", str(plan_log), "-o", str(tmp_path / "c.ehm"),
                                  "--config", str(bad)])  # fmt: skip
    assert refused.exit_code == 2
    assert "[queries] has no setting 'epochs' (it is in [learning])" in refused.output
