"""Pictures of a map, off-screen PNGs: occupancy slices through its volume, a rendered mesh
coloured by height, a 2D grid as an image, what changed between two maps."""

from __future__ import annotations

from collections.abc import Callable
from os import PathLike

import numpy as np

from ehm.changes import MapChanges
from ehm.errors import InputError
from ehm.grid.occupancy_grid import OccupancyGrid
from ehm.hilbert_map import HilbertMap
from ehm.viz.colors import HEIGHT_COLORMAP, height_range
from ehm.viz.render import Camera, render_mesh


def pyplot():
    """matplotlib.pyplot drawing off-screen (the Agg backend)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def occupancy_slices(
    hilbert_map: HilbertMap,
    low: np.ndarray,
    high: np.ndarray,
    path: str | PathLike[str],
    exact_occupancy: Callable[[np.ndarray], np.ndarray] | None = None,
    heights: tuple[float, ...] | None = None,
    resolution: float = 0.025,
    std: bool = False,
) -> None:
    """Write a PNG of horizontal occupancy slices (3D maps, at `heights` metres; default four
    evenly inside [low, high]) or of the whole plane (2D maps) over the box [low, high].
    exact_occupancy: when given, the true occupancy of (n, d) points ((n,) bool, for example
    a simulated scene's `occupied`), drawn as contours of the exact surfaces. std: draw the
    standard deviation of the occupancy instead (from 0 to its value where nothing was
    observed, read beyond the map's extent)."""
    plt = pyplot()
    quantity = "std of occupancy" if std else "occupancy"
    if std:
        extent = hilbert_map.extent()
        beyond = extent[1:] + (extent[1] - extent[0]) + 1.0  # where no kernel reaches
        unobserved = hilbert_map.occupancy(beyond, return_std=True)[1][0]
        colours = {"cmap": "magma", "vmin": 0.0, "vmax": unobserved}
    else:
        colours = {"cmap": "viridis", "vmin": 0.0, "vmax": 1.0}

    xs = np.arange(low[0], high[0], resolution)
    ys = np.arange(low[1], high[1], resolution)
    grid_x, grid_y = np.meshgrid(xs, ys)
    planar = np.column_stack([grid_x.ravel(), grid_y.ravel()])
    if hilbert_map.dim == 2:
        levels: tuple[float | None, ...] = (None,)
    elif heights is None:
        levels = tuple(np.linspace(low[2], high[2], 6)[1:-1])
    else:
        levels = heights
    figure, axes = plt.subplots(1, len(levels), figsize=(4.2 * len(levels), 4), squeeze=False)
    for axis, z in zip(axes[0], levels, strict=True):
        points = planar if z is None else np.column_stack([planar, np.full(len(planar), z)])
        if std:
            _, values = hilbert_map.occupancy(points, return_std=True)
        else:
            values = hilbert_map.occupancy(points)
        image = axis.imshow(
            values.reshape(grid_x.shape),
            origin="lower",
            extent=(xs[0], xs[-1], ys[0], ys[-1]),
            **colours,
        )
        if exact_occupancy is not None:
            truth = exact_occupancy(points).reshape(grid_x.shape).astype(float)
            axis.contour(grid_x, grid_y, truth, levels=[0.5], colors="white", linewidths=0.6)
        axis.set_title(quantity if z is None else f"{quantity} at z = {z:.2f} m")
        axis.set_xlabel("x (m)")
        axis.set_ylabel("y (m)")
    label = "std of p(occupied)" if std else "p(occupied)"
    figure.colorbar(image, ax=axes[0].tolist(), shrink=0.8, label=label)
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)


def mesh_picture(
    vertices: np.ndarray,
    faces: np.ndarray,
    path: str | PathLike[str],
    camera: Camera | None = None,
    cut_above: float | None = None,
    title: str | None = None,
) -> None:
    """Write a PNG of a mesh rendered off-screen and coloured by height, with a height colour
    bar. vertices: (V, 3) metres, world frame; faces: (F, 3). cut_above: leave out faces above
    this height, metres (to look into rooms)."""
    import matplotlib

    plt = pyplot()

    camera = camera or Camera()
    if cut_above is not None and len(faces):
        faces = faces[vertices[faces][:, :, 2].mean(axis=1) <= cut_above]
    if len(faces) == 0:
        raise InputError("nothing to draw: the mesh has no faces (below the cut)")
    heights = height_range(vertices, faces)
    image, _ = render_mesh(vertices, faces, camera, heights)
    figure, axis = plt.subplots(figsize=(camera.width / 100 + 1.6, camera.height / 100 + 0.6))
    axis.imshow(image)
    axis.set_axis_off()
    axis.set_title(title or f"{len(faces)} faces, azimuth {camera.azimuth:g} deg")
    colors = matplotlib.cm.ScalarMappable(
        matplotlib.colors.Normalize(*heights), matplotlib.colormaps[HEIGHT_COLORMAP]
    )
    figure.colorbar(colors, ax=axis, shrink=0.7, label="height z (m)")
    figure.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(figure)


def grid_picture(grid: OccupancyGrid, path: str | PathLike[str], title: str | None = None) -> None:
    """Write a PNG of a 2D grid's occupancy probabilities, x to the right and y up."""
    plt = pyplot()

    if grid.dim != 2:
        raise InputError(f"grid_picture draws 2D grids, this one is {grid.dim}D")
    (x0, y0), (x1, y1) = grid.bounds
    figure, axis = plt.subplots(figsize=(8, 8 * (y1 - y0) / (x1 - x0) + 0.6))
    image = axis.imshow(
        grid.probability.T,
        origin="lower",
        extent=(x0, x1, y0, y1),
        cmap="gray_r",
        vmin=0.0,
        vmax=1.0,
    )
    axis.set_title(title or f"occupancy, {grid.resolution} m voxels")
    axis.set_xlabel("x (m)")
    axis.set_ylabel("y (m)")
    figure.colorbar(image, ax=axis, shrink=0.8, label="p(occupied)")
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)


def changes_picture(
    changes: MapChanges, path: str | PathLike[str], title: str | None = None
) -> None:
    """Write a PNG of what changed between two maps (ehm.changes), seen from above, x to the
    right and y up: what appeared in blue and what vanished in red, over what is occupied in
    both in grey, darker where a column holds more of it (a 3D map's walls over its floor)."""
    import matplotlib

    plt = pyplot()
    (x0, y0), (x1, y1) = changes.bounds[0, :2], changes.bounds[1, :2]
    shape = np.round((changes.bounds[1, :2] - changes.bounds[0, :2]) / changes.resolution)
    stayed = np.zeros(tuple(shape.astype(int)))
    np.add.at(stayed, _columns(changes, changes.stayed), 1.0)
    full = np.percentile(stayed[stayed > 0], 95) if stayed.any() else 1.0
    picture = np.repeat((1.0 - 0.75 * np.minimum(stayed / full, 1.0))[..., None], 3, axis=-1)
    legend = []
    for centres, colour, label in (
        (changes.appeared, "tab:blue", "appeared"),
        (changes.vanished, "tab:red", "vanished"),
    ):
        picture[_columns(changes, centres)] = matplotlib.colors.to_rgb(colour)
        legend.append(
            matplotlib.patches.Patch(color=colour, label=f"{label} ({len(centres)} voxels)")
        )
    legend.append(matplotlib.patches.Patch(color="0.25", label="occupied in both"))
    figure, axis = plt.subplots(figsize=(8, 8 * (y1 - y0) / (x1 - x0) + 0.6))
    axis.imshow(
        picture.transpose(1, 0, 2), origin="lower", extent=(x0, x1, y0, y1), interpolation="nearest"
    )
    axis.legend(handles=legend, loc="upper right", fontsize=8)
    axis.set_title(title or f"changes, {changes.resolution} m voxels")
    axis.set_xlabel("x (m)")
    axis.set_ylabel("y (m)")
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)


def _columns(changes: MapChanges, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The (x, y) cell of each of (n, d) voxel `centres` in a picture of `changes` from
    above: index arrays (n,) each."""
    cells = np.floor((centres[:, :2] - changes.bounds[0, :2]) / changes.resolution)
    return cells[:, 0].astype(np.int64), cells[:, 1].astype(np.int64)
