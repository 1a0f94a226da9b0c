"""The command line's answer to mistakes: one line on stderr, exit status 2, before any work,
and never a traceback (but with --debug); outputs never written over inputs or without
--force."""

import json
import struct
import zlib

import numpy as np
import pytest
from typer.testing import CliRunner

import ehm
from ehm.cli import app

runner = CliRunner(env={"COLUMNS": "240"})


def fails(args: list[str], message: str, code: int = 2):
    """Run the command; it must end with `code` and `message` on stderr, nothing on stdout
    but progress, and no traceback."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == code, result.output
    assert message in " ".join(result.stderr.split()), result.stderr
    assert result.stderr.lstrip().startswith("error:"), result.stderr
    assert "Traceback" not in result.output and "error:" not in result.stdout
    return result


@pytest.fixture(scope="module")
def map_file(tmp_path_factory, plan_log):
    path = tmp_path_factory.mktemp("errors") / "plan.ehm"
    result = runner.invoke(app, ["map", str(plan_log), "-o", str(path)])
    assert result.exit_code == 0, result.output
    return path


def test_outputs_are_checked_before_any_work(plan_log, tmp_path):
    fails(["map", plan_log, "-o", tmp_path / "no" / "m.ehm"], "folder")
    fails(["map", plan_log, "-o", tmp_path / "no" / "m.ehm"], "does not exist")
    (tmp_path / "file").write_text("x")
    fails(["map", plan_log, "-o", tmp_path / "file" / "m.ehm"], "file is a file, not a folder")
    fails(["map", plan_log, "-o", tmp_path], "is a folder: expected a file name")
    fails(["eval", "--json", tmp_path / "no" / "r.json"], "does not exist")
    fails(["eval", "--plots", tmp_path / "file" / "plots"], "is a file, not a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_an_input_is_never_overwritten_and_outputs_need_force(map_file, plan_log, tmp_path):
    before = plan_log.read_bytes()
    for force in ([], ["--force"]):
        fails(["map", plan_log, "-o", plan_log, *force], "is an input: writing it would destroy")
    assert plan_log.read_bytes() == before
    output = tmp_path / "m.ehm"
    output.write_bytes(b"precious")
    fails(["map", plan_log, "-o", output], "m.ehm exists: --force overwrites it")
    assert output.read_bytes() == b"precious"
    result = runner.invoke(app, ["map", str(plan_log), "-o", str(output), "--force"])
    assert result.exit_code == 0, result.output
    assert ehm.load(output).n_scans_ == 5
    points = tmp_path / "q.csv"
    points.write_text("0,0\n")
    fails(["query", map_file, points, "-o", points, "--force"], "is an input")
    fails(["grid", map_file, "-o", map_file, "--force"], "expected a name ending in .npz")


def test_output_names_say_what_they_hold(map_file, tmp_path):
    fails(["grid", map_file, "-o", tmp_path / "g"], "g: expected a name ending in .npz")
    fails(["mesh", map_file, "-o", tmp_path / "m.obj"], "expected a name ending in .ply")
    fails(["render", map_file, "-o", tmp_path / "r.jpg"], "expected a name ending in .png")
    same = tmp_path / "r.png"
    fails(["render", map_file, "-o", same, "--std", same], "must name different files")
    assert list(tmp_path.iterdir()) == []


def test_options_out_of_range_are_named(map_file, plan_log, tmp_path):
    out = tmp_path / "r.png"
    fails(["render", map_file, "-o", out, "--azimuth", "nan"], "azimuth must be a finite angle")
    fails(["render", map_file, "-o", out, "--elevation", "90"], "elevation must lie inside")
    fails(["render", map_file, "-o", out, "--cut-above", "inf"], "--cut-above must be a finite")
    fails(["grid", map_file, "-o", tmp_path / "g.npz", "--max-gib", "nan"], "--max-gib must be")
    fails(["grid", map_file, "-o", tmp_path / "g.npz", "--bounds", "0,0,a,1"], "--bounds:")
    fails(["query", map_file, tmp_path / "none.csv", "--mode", "fast"], "--mode must be batch or")
    fails(["eval", "--resolution", "0"], "resolution must be a positive number of metres")
    fails(["eval", "--seeds", "-1"], "seeds must be integers >= 0, got -1")
    fails(["eval", "--seeds", "1.5"], "--seeds: invalid literal for int()")
    fails(["map", plan_log, "-o", tmp_path / "m.ehm", "--origin", "0,0,0"], "carmen files hold")
    fails(["map", plan_log, "-o", tmp_path / "m.ehm", "--max-range", "-1"], "max_range must be")
    fails(["map", plan_log, "-o", tmp_path / "m.ehm", "--calib", "identity"], "calib is for KITTI")
    missing = tmp_path / "poses.txt"
    fails(["map", plan_log, "-o", tmp_path / "m.ehm", "--poses", missing], "carmen files hold")
    assert list(tmp_path.iterdir()) == []


def test_bad_files_are_named(map_file, tmp_path):
    (tmp_path / "folder.ehm").mkdir()
    fails(["info", tmp_path / "folder.ehm"], "folder.ehm: a folder without index.json: neither")
    fails(["info", tmp_path / "none.ehm"], "none.ehm: no such file")
    header_row = tmp_path / "header.csv"
    header_row.write_text("x,y\n1,2\n")
    fails(["query", map_file, header_row], "header.csv: expected 2 comma-separated numbers")
    spaces = tmp_path / "spaces.csv"
    spaces.write_text("1 2\n3 4\n")
    fails(["query", map_file, spaces], "spaces.csv: expected 2 comma-separated numbers")
    garbage = tmp_path / "garbage.npy"
    garbage.write_bytes(b"\x93NUMPY garbage")
    fails(["query", map_file, garbage], "garbage.npy: not a NumPy array file")


def rewrite_header(source, target, change):
    """Copy a map file with its JSON header changed by `change` and a valid checksum."""
    data = source.read_bytes()
    magic, version, length = struct.unpack_from("<8sIQ", data)
    header = json.loads(data[20 : 20 + length])
    change(header)
    text = json.dumps(header).encode()
    body = struct.pack("<8sIQ", magic, version, len(text)) + text + data[20 + length : -4]
    target.write_bytes(body + struct.pack("<I", zlib.crc32(body)))


def test_a_checksummed_file_with_a_bad_config_is_named(map_file, tmp_path):
    bad = tmp_path / "bad.ehm"
    rewrite_header(map_file, bad, lambda h: h["config"].update(l2=-1.0))
    fails(["info", bad], "bad.ehm: inconsistent content (MapConfig.l2 must be >= 0, got -1.0)")
    rewrite_header(map_file, bad, lambda h: h["config"].update(colour="red"))
    fails(["info", bad], "unknown MapConfig setting(s): colour")
    rewrite_header(map_file, bad, lambda h: h.pop("n_scans"))
    fails(["info", bad], "bad.ehm: inconsistent content")
    same = tmp_path / "same.ehm"
    rewrite_header(map_file, same, lambda h: None)
    assert runner.invoke(app, ["info", str(same)]).exit_code == 0


def test_an_empty_map_is_a_map_every_command_handles(tmp_path):
    log = tmp_path / "sparse.log"
    log.write_text("FLASER 2 1.0 2.0 0.0 0.0 0.0 0 0 0 0 h 0\n")
    path = tmp_path / "empty.ehm"
    # Both rays cut before their hits: too little free space along them for a cluster.
    result = runner.invoke(app, ["map", str(log), "-o", str(path), "--max-range", "0.5"])
    assert result.exit_code == 0, result.output
    assert "the map has no clusters" in result.stderr
    info = runner.invoke(app, ["info", str(path)])
    assert info.exit_code == 0 and "the map is empty, every point reads 0.5" in info.output
    fails(["grid", path, "-o", tmp_path / "g.npz"], "the map has no clusters")
    fails(["render", path, "-o", tmp_path / "r.png"], "give bounds for a grid of it anyway")
    bounds = ["--bounds", "-1,-1,1,1", "--resolution", "0.5"]
    result = runner.invoke(app, ["grid", str(path), "-o", str(tmp_path / "g.npz"), *bounds])
    assert result.exit_code == 0, result.output
    np.testing.assert_array_equal(np.load(tmp_path / "g.npz")["probability"], 0.5)
    points = tmp_path / "q.csv"
    points.write_text("0,0\n5,5\n")
    result = runner.invoke(app, ["query", str(path), str(points)])
    assert result.exit_code == 0 and result.stdout.split() == ["0.500000", "0.500000"]


def test_a_far_glitch_is_cut_by_max_range(tmp_path, rng):
    """A point a million kilometres out among points 3 m away: refused by name without a range
    limit, one ray without return with one."""
    directions = rng.normal(size=(3000, 3))
    sphere = 3.0 * directions / np.linalg.norm(directions, axis=1)[:, None]
    glitch = tmp_path / "glitch.xyz"
    np.savetxt(glitch, np.vstack([sphere, [[1e9, 0.0, 0.0]]]))
    fails(["map", glitch, "-o", tmp_path / "a.ehm"], "set max_range (ehm map --max-range)")
    output = tmp_path / "b.ehm"
    result = runner.invoke(app, ["map", str(glitch), "-o", str(output), "--max-range", "30"])
    assert result.exit_code == 0, result.output
    glitch_map = ehm.load(output)
    assert glitch_map.config.max_range == 30.0
    # Free clusters along the cut ray reach 30 m, no further; the glitch's place is unknown.
    assert np.linalg.norm(glitch_map.clusters_.means, axis=1).max() < 30.5
    assert glitch_map.occupancy(np.array([[1e9, 0.0, 0.0]]))[0] == 0.5


def test_debug_shows_the_traceback_and_bugs_say_so(tmp_path, monkeypatch):
    (tmp_path / "junk.ehm").write_bytes(b"junk")
    result = runner.invoke(app, ["--debug", "info", str(tmp_path / "junk.ehm")])
    assert isinstance(result.exception, ehm.MapFileError)

    def broken(path):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr("ehm.maps.load", broken)
    result = fails(["info", tmp_path / "junk.ehm"], "ZeroDivisionError: division by zero", 1)
    assert "This is a bug in ehm; `ehm --debug ...` shows where it happened." in result.stderr
    result = runner.invoke(app, ["--debug", "info", str(tmp_path / "junk.ehm")])
    assert isinstance(result.exception, ZeroDivisionError)


def test_a_closed_pipe_is_not_called_a_bug(tmp_path, monkeypatch):
    """`ehm query MAP POINTS | head` closes the pipe early: a quiet end, not a bug report."""

    def closed(path):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr("ehm.maps.load", closed)
    result = runner.invoke(app, ["info", str(tmp_path / "m.ehm")])
    assert result.exit_code == 1 and "bug" not in result.output


def test_a_format_that_cannot_fit_an_input_is_refused_by_name(tmp_path):
    (tmp_path / "a.pcd").write_text("not read")
    fails(
        ["map", tmp_path / "a.pcd", "-f", "bag", "-o", tmp_path / "m.ehm"],
        "a.pcd: is not a ROS bag",
    )
    fails(
        ["map", tmp_path / "a.pcd", "-f", "tum", "-o", tmp_path / "m.ehm"],
        "is not a folder of tum depth frames",
    )
    fails(
        ["map", tmp_path, "-f", "xyz", "-o", tmp_path / "m.ehm"], "is a folder; xyz scans are files"
    )


def test_depth_options_are_checked_and_kept_to_depth_frames(tmp_path, plan_log):
    out = tmp_path / "m.ehm"
    fails(
        ["map", plan_log, "--intrinsics", "1,2,3,4", "-o", out], "are for depth frames, not carmen"
    )
    fails(["map", plan_log, "--depth-scale", "0", "-o", out], "are for depth frames, not carmen")
    (tmp_path / "fr1" / "depth").mkdir(parents=True)
    (tmp_path / "fr1" / "poses.txt").write_text("depth/0.png 0 0 0 0 0 0 1\n")
    fails(["map", tmp_path / "fr1", "--intrinsics", "1,2,3", "-o", out], "intrinsics are 4 numbers")
    fails(
        ["map", tmp_path / "fr1", "--depth-scale", "-5", "-o", out], "depth scale is the raw units"
    )
    fails(["map", tmp_path / "fr1", "--fov", "240", "-o", out], "fov is for CARMEN logs, not tum")


def test_what_a_reader_assumes_is_said_in_a_note(tmp_path):
    from PIL import Image

    folder = tmp_path / "seq-01"
    folder.mkdir()
    depth = np.full((48, 64), 1500, dtype=np.uint16)
    Image.fromarray(depth).save(folder / "frame-000000.depth.png")
    np.savetxt(folder / "frame-000000.pose.txt", np.eye(4))
    result = runner.invoke(app, ["map", str(folder), "-o", str(tmp_path / "m.ehm"), "--quiet"])
    assert result.exit_code == 0, result.output
    assert "note: seq-01: no camera-intrinsics.txt, so 7-Scenes' Kinect is assumed" in " ".join(
        result.stderr.split()
    )


def test_notes_come_while_scans_are_read_too(tmp_path, cloud_in_feet):
    """A LAS file's units are read with its points, while mapping: the note still comes, once
    a file, as a `note:` line."""
    result = runner.invoke(
        app, ["map", *map(str, cloud_in_feet), "-o", str(tmp_path / "m.ehm"), "--quiet"]
    )
    assert result.exit_code == 0, result.output
    notes = [line for line in result.stderr.splitlines() if line.startswith("note:")]
    assert len(notes) == 2 and all("US survey feet" in note for note in notes)


@pytest.fixture
def cloud_in_feet(tmp_path):
    """Two LAS files whose GeoTIFF keys say US survey feet."""
    pytest.importorskip("laspy")
    from las_files import geo_keys, write_las

    rng = np.random.default_rng(0)
    return [
        write_las(tmp_path / name, rng.uniform(-5, 5, (500, 3)), geo_keys((3076, 9003)))
        for name in ("a.las", "b.las")
    ]
