"""Make the pictures of the documentation (docs/images) with the project itself:

    .venv/bin/python docs/pictures.py

The virtual room mapped by one LiDAR scan (its mesh, occupancy slices and their standard
deviation), the 2D floor plan exported for nav2, and what changed in the changing room between
the cart's last scan and the end. The viewer's picture (images/viewer.png) needs a browser:
benchmarks/viewer.py takes it.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

import ehm
from ehm.eval.datasets import floor_plan_2d, virtual_room
from ehm.eval.datasets.changing import changing_room
from ehm.io.exports import write_map_server
from ehm.viz.pictures import changes_picture, grid_picture, mesh_picture, occupancy_slices

IMAGES = Path(__file__).resolve().parent / "images"


def main() -> None:
    IMAGES.mkdir(exist_ok=True)
    data = virtual_room()
    room = ehm.HilbertMap().fit(data.scans)
    vertices, faces = room.grid(resolution=0.05).mesh()
    mesh_picture(vertices, faces, IMAGES / "room_mesh.png", cut_above=2.2, title="virtual room")
    low, high = data.scene.box_min.min(axis=0), data.scene.box_max.max(axis=0)
    heights = (0.3, 0.75, 1.2, 2.0)
    occupancy_slices(room, low, high, IMAGES / "room_slices.png", data.scene.occupied, heights)
    occupancy_slices(room, low, high, IMAGES / "room_std.png", heights=heights, std=True)

    plan = ehm.HilbertMap().fit(floor_plan_2d().scans)
    grid_picture(plan.grid(resolution=0.05), IMAGES / "floor_plan.png", title="floor plan")
    with tempfile.TemporaryDirectory() as folder:
        write_map_server(plan.grid(resolution=0.05), Path(folder) / "floor.pgm")
        nav2 = Image.open(Path(folder) / "floor.pgm")
        nav2.resize((4 * nav2.width, 4 * nav2.height), Image.NEAREST).save(
            IMAGES / "floor_nav2.png"
        )

    scenes = changing_room()
    before, after = ehm.HilbertMap(), ehm.HilbertMap(pass_retraction=0.5)
    for i, scan in enumerate(scenes.scans):
        if i <= 4:
            before.integrate_scan(scan)
        after.integrate_scan(scan)
    bounds = np.array([[-4.0, -3.0, 0.0], [4.0, 3.0, 2.5]])
    changes = ehm.diff(before, after, bounds=bounds)
    title = "changing room: after scan 4 and at the end"
    changes_picture(changes, IMAGES / "changes.png", title=title)


if __name__ == "__main__":
    main()
