"""RGB-D frames in the Redwood layout of Open3D's examples: depth/, a .log trajectory and the
camera as a PinholeCameraIntrinsic JSON."""

import json

import numpy as np
import pytest
from depth_folders import redwood_sequence

from ehm.errors import AssumptionWarning, FileReadError, InputError
from ehm.eval.datasets.real import data_dir
from ehm.io.readers import guess_format, read_scans


def test_redwood_frames_are_millimetres_through_the_camera_file(tmp_path):
    folder = redwood_sequence(tmp_path / "living_room")
    assert guess_format(folder) == "redwood"
    with pytest.warns(AssumptionWarning, match="read as millimetres, Open3D's convention"):
        first, second = read_scans(folder)
    np.testing.assert_allclose(first.points_world, [[4.0, 1.0, 2.0]])  # column-major K
    np.testing.assert_allclose(second.origin, [1.0, 0.0, 0.0])


def test_redwood_mistakes_are_named(tmp_path):
    folder = redwood_sequence(tmp_path / "seq")
    camera = json.loads((folder / "camera.json").read_text())
    (folder / "camera.json").write_text(json.dumps({**camera, "intrinsic_matrix": [0] * 9}))
    with pytest.raises(FileReadError, match=r"camera\.json: not a camera's intrinsic_matrix"):
        read_scans(folder)
    (folder / "camera.json").unlink()
    with pytest.raises(InputError, match=r"no camera file .* --intrinsics FX,FY,CX,CY"):
        read_scans(folder)
    (folder / "trajectory.log").write_text("0 0 1\n1 0 0 0\n")
    with pytest.raises(FileReadError, match=r"trajectory\.log: 2 lines: a Redwood trajectory"):
        read_scans(folder, intrinsics=[2, 2, 0, 0], depth_scale=1000)
    (folder / "trajectory.log").write_text("5 5 6\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    with pytest.raises(FileReadError, match="a pose for frame 5, and depth/ holds 2 images"):
        read_scans(folder, intrinsics=[2, 2, 0, 0], depth_scale=1000)


def test_the_shared_millimetre_sequence_reads_at_its_own_scale():
    """Open3D's five Redwood frames: 87 % of pixels valid, depths 0.96-2.70 m, the camera
    moving about 10 cm; read as TUM's fifths of a millimetre they would be 5x too near."""
    folder = data_dir() / "rgbd_mm"
    if not folder.exists():
        pytest.skip(f"{folder} not found (set EHM_DATA_DIR to the data folder)")
    with pytest.warns(AssumptionWarning):
        scans = read_scans(folder)
    assert len(scans) == 5
    for scan in scans:
        depth = np.linalg.norm(scan.points_world - scan.origin, axis=1)
        assert depth.min() > 0.9 and depth.max() < 3.5
        assert len(scan) > 0.8 * 640 * 480 / 4
    travel = np.linalg.norm(scans[-1].origin - scans[0].origin)
    assert 0.03 < travel < 0.3
