"""Off-screen pictures of triangle meshes: an orthographic camera, a depth buffer and flat
shading, coloured by height. Needs no display and no graphics library.

Screen coordinates: x to the right and y down, in pixels (pixel (r, c) covers
[c, c + 1) x [r, r + 1)); depth grows toward the viewer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ehm.errors import InputError
from ehm.viz.colors import height_colors, height_range


@dataclass(frozen=True)
class Camera:
    """Orthographic view from `azimuth` degrees (counter-clockwise from +x) and `elevation`
    degrees above the horizon, `width` x `height` pixels."""

    azimuth: float = -60.0
    elevation: float = 45.0
    width: int = 1200
    height: int = 900

    def __post_init__(self) -> None:
        if not np.isfinite(self.azimuth):
            raise InputError(f"camera azimuth must be a finite angle, got {self.azimuth}")
        if not -90.0 < self.elevation < 90.0:
            raise InputError(
                f"camera elevation must lie inside (-90, 90) degrees, got {self.elevation}"
            )
        if self.width < 1 or self.height < 1:
            raise InputError(f"picture size must be positive, got {self.width} x {self.height}")

    def rotation(self) -> np.ndarray:
        """(3, 3) R_camera_world: rows are the camera's right, up and toward-viewer axes."""
        az, el = np.deg2rad(self.azimuth), np.deg2rad(self.elevation)
        toward = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        right = np.cross(np.array([0.0, 0.0, 1.0]), toward)
        right /= np.linalg.norm(right)
        return np.stack([right, np.cross(toward, right), toward])

    def project(self, vertices: np.ndarray, margin: float = 0.04) -> np.ndarray:
        """(V, 3) screen x, y (pixels) and depth (metres) of (V, 3) world points, metres,
        scaled so that all of them fit the picture."""
        camera = vertices @ self.rotation().T
        low, high = camera[:, :2].min(axis=0), camera[:, :2].max(axis=0)
        extent = np.maximum(high - low, 1e-9)
        usable = np.array([self.width, self.height]) * (1.0 - 2.0 * margin)
        scale = float(np.min(usable / extent))
        centre = 0.5 * (low + high)
        x = 0.5 * self.width + (camera[:, 0] - centre[0]) * scale
        y = 0.5 * self.height - (camera[:, 1] - centre[1]) * scale
        return np.column_stack([x, y, camera[:, 2]])


def face_colors(
    vertices: np.ndarray, faces: np.ndarray, camera: Camera, heights: tuple[float, float]
) -> np.ndarray:
    """(F, 3) float RGB in [0, 1] per face: HEIGHT_COLORMAP at the face's height (z over the
    range `heights`, metres) times Lambert shading from a light behind the viewer's left
    shoulder (both sides of a face are lit)."""
    corners = vertices[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    right, up, toward = camera.rotation()
    light = toward + 0.5 * up - 0.4 * right
    light /= np.linalg.norm(light)
    shade = 0.3 + 0.7 * np.abs(normals @ light)
    return height_colors(corners[:, :, 2].mean(axis=1), heights) * shade[:, None]


def render_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    camera: Camera | None = None,
    heights: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Picture of a mesh: (height, width, 3) uint8 RGB on white, and the (height, width) bool
    mask of pixels the mesh covers. vertices: (V, 3) metres, world frame; faces: (F, 3);
    heights: z range, metres, the colours span (default: the faces' own)."""
    camera = camera or Camera()
    image = np.ones((camera.height, camera.width, 3))
    depth = np.full((camera.height, camera.width), -np.inf)
    if len(faces):
        used, faces = np.unique(faces, return_inverse=True)  # frame only the drawn vertices
        vertices, faces = vertices[used], faces.reshape(-1, 3)
        screen = camera.project(vertices)
        colors = face_colors(vertices, faces, camera, heights or height_range(vertices, faces))
        rasterize(screen, faces.astype(np.int64), colors, image, depth)
    return np.round(image * 255).astype(np.uint8), np.isfinite(depth)


@numba.njit(cache=True)
def rasterize(screen, faces, colors, image, depth):  # pragma: no cover - compiled
    """Draw faces (F, 3) of screen vertices (V, 3) with flat colors (F, 3) into image (H, W, 3)
    where they are nearer than depth (H, W), in place. A pixel belongs to a face when its
    centre lies inside or on the face's edges."""
    height, width = depth.shape
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        ax, ay, az = screen[a, 0], screen[a, 1], screen[a, 2]
        bx, by, bz = screen[b, 0], screen[b, 1], screen[b, 2]
        cx, cy, cz = screen[c, 0], screen[c, 1], screen[c, 2]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if area == 0.0:
            continue
        col0 = max(int(np.floor(min(ax, bx, cx) - 0.5)), 0)
        col1 = min(int(np.ceil(max(ax, bx, cx) - 0.5)), width - 1)
        row0 = max(int(np.floor(min(ay, by, cy) - 0.5)), 0)
        row1 = min(int(np.ceil(max(ay, by, cy) - 0.5)), height - 1)
        for row in range(row0, row1 + 1):
            py = row + 0.5
            for col in range(col0, col1 + 1):
                px = col + 0.5
                wa = ((cx - bx) * (py - by) - (cy - by) * (px - bx)) / area
                wb = ((ax - cx) * (py - cy) - (ay - cy) * (px - cx)) / area
                wc = ((bx - ax) * (py - ay) - (by - ay) * (px - ax)) / area
                if wa < 0.0 or wb < 0.0 or wc < 0.0:
                    continue
                z = wa * az + wb * bz + wc * cz
                if z > depth[row, col]:
                    depth[row, col] = z
                    image[row, col, 0] = colors[f, 0]
                    image[row, col, 1] = colors[f, 1]
                    image[row, col, 2] = colors[f, 2]


def rasterize_reference(
    screen: np.ndarray, faces: np.ndarray, colors: np.ndarray, image: np.ndarray, depth: np.ndarray
) -> None:
    """Plain NumPy twin of `rasterize`, one face at a time."""
    height, width = depth.shape
    for f, (a, b, c) in enumerate(faces):
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = screen[a], screen[b], screen[c]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if area == 0.0:
            continue
        col0 = max(int(np.floor(min(ax, bx, cx) - 0.5)), 0)
        col1 = min(int(np.ceil(max(ax, bx, cx) - 0.5)), width - 1)
        row0 = max(int(np.floor(min(ay, by, cy) - 0.5)), 0)
        row1 = min(int(np.ceil(max(ay, by, cy) - 0.5)), height - 1)
        if col1 < col0 or row1 < row0:
            continue
        py, px = np.meshgrid(
            np.arange(row0, row1 + 1) + 0.5, np.arange(col0, col1 + 1) + 0.5, indexing="ij"
        )
        wa = ((cx - bx) * (py - by) - (cy - by) * (px - bx)) / area
        wb = ((ax - cx) * (py - cy) - (ay - cy) * (px - cx)) / area
        wc = ((bx - ax) * (py - ay) - (by - ay) * (px - ax)) / area
        z = wa * az + wb * bz + wc * cz
        window = depth[row0 : row1 + 1, col0 : col1 + 1]
        drawn = (wa >= 0.0) & (wb >= 0.0) & (wc >= 0.0) & (z > window)
        window[drawn] = z[drawn]
        image[row0 : row1 + 1, col0 : col1 + 1][drawn] = colors[f]
