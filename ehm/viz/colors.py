"""Colours by height, the same in rendered pictures and in PLY files."""

from __future__ import annotations

import numpy as np

HEIGHT_COLORMAP = "turbo"


def height_range(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, float]:
    """Lowest and highest z, metres, of the vertices the faces use."""
    z = vertices[np.unique(faces), 2]
    return float(z.min()), float(z.max())


def height_colors(z: np.ndarray, heights: tuple[float, float]) -> np.ndarray:
    """(n, 3) float RGB in [0, 1]: HEIGHT_COLORMAP at heights z (n,), metres, over the range
    `heights` (clipped at its ends)."""
    import matplotlib

    low, high = heights
    fraction = np.clip((z - low) / max(high - low, 1e-9), 0.0, 1.0)
    return matplotlib.colormaps[HEIGHT_COLORMAP](fraction)[:, :3]


def vertex_colors(vertices: np.ndarray) -> np.ndarray:
    """(V, 3) uint8 RGB of each vertex (V, 3), metres, by its height over the vertices' own
    range of heights: the colours of rendered pictures, for PLY files."""
    if len(vertices) == 0:
        return np.zeros((0, 3), dtype=np.uint8)
    z = vertices[:, 2]
    return np.round(255 * height_colors(z, (z.min(), z.max()))).astype(np.uint8)
