"""TUM RGB-D depth frames."""

import numpy as np

from ehm.io.readers import read_scans
from ehm.io.tum import read_tum


def test_tum_depth_frames(tmp_path):
    from PIL import Image

    depth = np.zeros((6, 8), dtype=np.uint16)
    depth[2, 4] = 10000  # 2 m at pixel (u=4, v=2)
    (tmp_path / "depth").mkdir()
    Image.fromarray(depth).save(tmp_path / "depth" / "1311877813.991479.png")
    (tmp_path / "depth" / "first.png").write_bytes(
        (tmp_path / "depth" / "1311877813.991479.png").read_bytes()
    )
    poses = "depth/1311877813.991479.png 1 2 3 0 0 0 1\ndepth/first.png 1 2 3 0 0 0 1\n"
    (tmp_path / "poses.txt").write_text("# header\n" + poses)
    assert len(read_scans(tmp_path)) == 2  # a folder with poses.txt reads as TUM
    scans = read_tum(tmp_path, fx=2.0, fy=2.0, cx=4.0, cy=1.0, pixel_stride=1)
    assert len(scans) == 2 and len(scans[0]) == 1
    # A frame's time is its name, where that is a number.
    assert scans[0].time == 1311877813.991479 and scans[1].time is None
    np.testing.assert_allclose(scans[0].points_world, [[1.0, 2.0 + 1.0, 3.0 + 2.0]])
