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
from ehm.eval.datasets.simulated import CityDrive
from ehm.grid.navigation import navigation_grid
from ehm.io.exports import write_map_server
from ehm.viz.pictures import (
    changes_picture,
    grid_picture,
    mesh_picture,
    occupancy_slices,
    pyplot,
)

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
    rays_picture(room, IMAGES / "room_rays.png")

    plan = ehm.HilbertMap().fit(floor_plan_2d().scans)
    grid_picture(plan.grid(resolution=0.05), IMAGES / "floor_plan.png", title="floor plan")
    with tempfile.TemporaryDirectory() as folder:
        write_map_server(navigation_grid(plan, resolution=0.05), Path(folder) / "floor.pgm")
        nav2 = Image.open(Path(folder) / "floor.pgm")
        nav2.resize((4 * nav2.width, 4 * nav2.height), Image.NEAREST).save(
            IMAGES / "floor_nav2.png"
        )

    drive = CityDrive(length=80.0, n_scans=16)
    city = ehm.TiledMap(tile_size=25.0, config=ehm.MapConfig.for_resolution(0.2))
    for scan in drive:
        city.integrate_scan(scan)
    vertices, faces = city.grid(resolution=0.2).mesh()
    mesh_picture(
        vertices, faces, IMAGES / "city_mesh.png", title="80 m of a city drive, 25 m tiles"
    )

    scenes = changing_room()
    before, after = ehm.HilbertMap(), ehm.HilbertMap()
    for i, scan in enumerate(scenes.scans):
        if i <= 4:
            before.integrate_scan(scan)
        after.integrate_scan(scan)
    bounds = np.array([[-4.0, -3.0, 0.0], [4.0, 3.0, 2.5]])
    changes = ehm.diff(before, after, bounds=bounds)
    title = "changing room: after scan 4 and at the end"
    changes_picture(changes, IMAGES / "changes.png", title=title)


def rays_picture(room: ehm.HilbertMap, path: Path) -> None:
    """The occupancy of a horizontal slice 1.2 m up, with rays cast from the sensor in it
    stopping where they meet a surface."""
    plt = pyplot()
    x, y = np.meshgrid(np.linspace(-4.2, 4.2, 337), np.linspace(-3.2, 3.2, 257))
    slice_points = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 1.2)])
    p = room.occupancy(slice_points).reshape(x.shape)
    angles = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
    directions = np.column_stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)])
    origin = room.sensor_path[0]
    distance = room.raycast(np.repeat(origin[None], len(angles), axis=0), directions, 10.0)
    figure, axis = plt.subplots(figsize=(8, 6))
    image = axis.imshow(
        p, origin="lower", extent=(-4.2, 4.2, -3.2, 3.2), cmap="Greys", vmin=0, vmax=1
    )
    for direction, d in zip(directions, np.minimum(distance, 10.0), strict=True):
        end = origin + d * direction
        axis.plot([origin[0], end[0]], [origin[1], end[1]], color="tab:orange", linewidth=0.8)
        axis.plot(end[0], end[1], "o", color="tab:red", markersize=2.5)
    axis.set_xlabel("x (m)")
    axis.set_ylabel("y (m)")
    axis.set_title("occupancy 1.2 m up; raycast from the sensor")
    figure.colorbar(image, ax=axis, shrink=0.8, label="p(occupied)")
    figure.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(figure)


if __name__ == "__main__":
    main()
