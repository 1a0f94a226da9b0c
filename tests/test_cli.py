import numpy as np
import pytest
from typer.testing import CliRunner

import ehm
from ehm.cli import app

runner = CliRunner(env={"COLUMNS": "240"})


@pytest.fixture(scope="module")
def map_file(tmp_path_factory, plan):
    folder = tmp_path_factory.mktemp("cli")
    log = folder / "plan.log"
    lines = []
    for scan in plan.scans:
        offsets = scan.points_world[scan.hit_mask] - scan.origin
        ranges = np.linalg.norm(offsets, axis=1)
        angles = np.arctan2(offsets[:, 1], offsets[:, 0])
        # Resample onto 180 beams from -90 to +89 degrees around heading 0.
        beams = np.full(180, 81.83)
        index = np.round(np.rad2deg(angles) + 90).astype(int)
        ok = (index >= 0) & (index < 180)
        beams[index[ok]] = ranges[ok]
        values = " ".join(f"{r:.4f}" for r in beams)
        lines.append(f"FLASER 180 {values} {scan.origin[0]} {scan.origin[1]} 0.0 0 0 0 0 h 0")
    log.write_text("\n".join(lines) + "\n")
    output = folder / "plan.ehm"
    result = runner.invoke(app, ["map", str(log), "-o", str(output), "--set", "neighbours=6"])
    assert result.exit_code == 0, result.output
    assert "5 scans" in result.output and "sgd" in result.output
    return output


def test_map_then_info_and_query(map_file, tmp_path):
    info = runner.invoke(app, ["info", str(map_file)])
    assert info.exit_code == 0, info.output
    assert "config.neighbours" in info.output and "6" in info.output
    points = np.array([[-3.0, -1.5], [6.0, -0.2]])
    np.save(tmp_path / "q.npy", points)
    np.savetxt(tmp_path / "q.csv", points, delimiter=",")
    expected = ehm.load(map_file).occupancy(points)
    out = runner.invoke(app, ["query", str(map_file), str(tmp_path / "q.csv")])
    assert out.exit_code == 0, out.output
    np.testing.assert_allclose(np.array(out.output.split(), float), expected, atol=1e-6)
    result = runner.invoke(
        app, ["query", str(map_file), str(tmp_path / "q.npy"), "-o", str(tmp_path / "p.npy")]
    )
    assert result.exit_code == 0, result.output
    np.testing.assert_array_equal(np.load(tmp_path / "p.npy"), expected)
    assert expected[0] < 0.5 < expected[1]  # a robot pose is free, the wall occupied


def test_bad_inputs_give_clear_errors(map_file, tmp_path):
    (tmp_path / "junk.ehm").write_bytes(b"junk")
    result = runner.invoke(app, ["info", str(tmp_path / "junk.ehm")])
    assert result.exit_code == 1 and "not an ehm map file" in result.output
    np.save(tmp_path / "q3.npy", np.zeros((2, 3)))
    result = runner.invoke(app, ["query", str(map_file), str(tmp_path / "q3.npy")])
    assert result.exit_code != 0 and "shape (n, 2)" in result.output
    result = runner.invoke(app, ["map", str(tmp_path / "nothing.ply"), "-o", "x.ehm"])
    assert result.exit_code != 0 and "no such file" in result.output
    result = runner.invoke(app, ["map", str(tmp_path / "q3.npy"), "-o", "x.ehm", "--set", "k=1"])
    assert result.exit_code != 0


def test_demo_writes_map_and_picture(tmp_path):
    result = runner.invoke(app, ["demo", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "ROC-AUC" in result.output and "near surfaces" in result.output
    assert (tmp_path / "virtual_room_slices.png").stat().st_size > 10_000
    assert ehm.load(tmp_path / "virtual_room.ehm").dim == 3
