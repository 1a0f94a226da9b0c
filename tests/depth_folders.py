"""Folders of depth frames in the layouts the readers know, written for tests."""

import json

import numpy as np


def seven_scenes_frames(folder, values):
    """7-Scenes frames: frame-00000i.depth.png reading `values[i]` mm at pixel (u=4, v=2),
    everything else 0 or 65535 (no reading), each frame 1 m further along x."""
    from PIL import Image

    folder.mkdir(parents=True, exist_ok=True)
    for i, value in enumerate(values):
        depth = np.zeros((6, 8), dtype=np.uint16)
        depth[0, :] = 65535
        depth[2, 4] = value
        Image.fromarray(depth).save(folder / f"frame-{i:06d}.depth.png")
        pose = np.eye(4)
        pose[0, 3] = i
        np.savetxt(folder / f"frame-{i:06d}.pose.txt", pose)
    return folder


def redwood_sequence(folder, n=2):
    """A Redwood sequence of `n` frames reading 2000 mm at pixel (u=4, v=2), each 1 m further
    along x, with trajectory.log and the camera's JSON (fx = fy = 2, cx 0, cy 1)."""
    from PIL import Image

    (folder / "depth").mkdir(parents=True)
    log = []
    for i in range(n):
        depth = np.zeros((6, 8), dtype=np.uint16)
        depth[2, 4] = 2000
        Image.fromarray(depth).save(folder / "depth" / f"{i:05d}.png")
        log += [f"{i} {i} {i + 1}", f"1 0 0 {i}", "0 1 0 0", "0 0 1 0", "0 0 0 1"]
    (folder / "trajectory.log").write_text("\n".join(log) + "\n")
    camera = {"width": 8, "height": 6, "intrinsic_matrix": [2, 0, 0, 0, 2, 0, 0, 1, 1]}
    (folder / "camera.json").write_text(json.dumps(camera))
    return folder
