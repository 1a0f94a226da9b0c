"""Pictures of a map: occupancy slices through its volume (off-screen, PNG)."""

from __future__ import annotations

from os import PathLike

import numpy as np

from ehm.datasets.scene import Scene
from ehm.model import HilbertMap


def occupancy_slices(
    hilbert_map: HilbertMap,
    low: np.ndarray,
    high: np.ndarray,
    path: str | PathLike[str],
    scene: Scene | None = None,
    heights: tuple[float, ...] = (0.3, 0.75, 1.2, 2.0),
    resolution: float = 0.025,
) -> None:
    """Write a PNG of horizontal occupancy slices (3D maps, at `heights` metres) or of the
    whole plane (2D maps) over the box [low, high]; the exact surfaces of `scene`, when
    given, are drawn as contours."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = np.arange(low[0], high[0], resolution)
    ys = np.arange(low[1], high[1], resolution)
    grid_x, grid_y = np.meshgrid(xs, ys)
    planar = np.column_stack([grid_x.ravel(), grid_y.ravel()])
    levels = heights if hilbert_map.dim == 3 else (None,)
    figure, axes = plt.subplots(1, len(levels), figsize=(4.2 * len(levels), 4), squeeze=False)
    for axis, z in zip(axes[0], levels, strict=True):
        points = planar if z is None else np.column_stack([planar, np.full(len(planar), z)])
        probability = hilbert_map.occupancy(points).reshape(grid_x.shape)
        image = axis.imshow(
            probability,
            origin="lower",
            extent=(xs[0], xs[-1], ys[0], ys[-1]),
            cmap="viridis",
            vmin=0.0,
            vmax=1.0,
        )
        if scene is not None:
            truth = scene.occupied(points).reshape(grid_x.shape).astype(float)
            axis.contour(grid_x, grid_y, truth, levels=[0.5], colors="white", linewidths=0.6)
        axis.set_title("occupancy" if z is None else f"occupancy at z = {z:.2f} m")
        axis.set_xlabel("x (m)")
        axis.set_ylabel("y (m)")
    figure.colorbar(image, ax=axes[0].tolist(), shrink=0.8, label="p(occupied)")
    figure.savefig(path, dpi=110)
    plt.close(figure)
