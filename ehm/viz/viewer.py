"""A map in the browser, served with viser (`pip install 'ehm[viewer]'`): for a 3D map its
surface at an occupancy level (a slider re-meshes it) coloured by height or by the occupancy's
standard deviation, a horizontal slice of the occupancy as a heat map at a chosen height, the
surface samples the map keeps, the sensor path and axes in metres; for a 2D map its grid as an
image with the sensor path.

    viewer = MapViewer(hilbert_map, resolution=0.1, port=8080)   # http://localhost:8080
    viewer.level.value = 0.7                                     # what the slider does

Nothing else in the package imports this module.
"""

from __future__ import annotations

import numpy as np

from ehm.hilbert_map import HilbertMap
from ehm.viz.colors import height_colors

INSTALL_HINT = "the viewer needs viser: pip install 'ehm[viewer]'"
# Colours of the sensor path and the surface samples, RGB 0-255.
PATH_COLOR = (230, 40, 40)
SAMPLE_COLOR = (40, 40, 40)


class MapViewer:
    """Serves `hilbert_map` at http://host:port (see the module). `surface` is the scene node
    of the current surface and `mesh` its trimesh.Trimesh (None where the grid does not cross
    the level, and for 2D maps)."""

    def __init__(
        self,
        hilbert_map: HilbertMap,
        resolution: float = 0.1,
        port: int = 8080,
        host: str = "127.0.0.1",
    ) -> None:
        viser = viser_module()
        self.map = hilbert_map
        self.grid = hilbert_map.grid(resolution=resolution, std=hilbert_map.dim == 3)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.surface = None
        self.mesh = None
        self.n_faces = 0
        self._aim_camera()
        self._show_axes_and_path()
        if hilbert_map.dim == 2:
            self._show_plane()
            return
        self.level = self.server.gui.add_slider("occupancy level", 0.05, 0.95, 0.05, 0.5)
        self.coloring = self.server.gui.add_dropdown(
            "colour by", ("height", "uncertainty (std)"), initial_value="height"
        )
        low, high = self.grid.bounds
        self.slice_height = self.server.gui.add_slider(
            "slice height (m)", float(low[2]), float(high[2]), self.grid.resolution,
            float(np.clip(1.0, low[2], high[2])),
        )  # fmt: skip
        self.show_slice = self.server.gui.add_checkbox("show slice", False)
        self.level.on_update(lambda _: self.show_surface())
        self.coloring.on_update(lambda _: self.show_surface())
        self.slice_height.on_update(lambda _: self.show_slice_plane())
        self.show_slice.on_update(lambda _: self.show_slice_plane())
        self._show_samples()
        self.show_surface()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def _aim_camera(self) -> None:
        """Start every browser looking down at the whole map from outside its box."""
        low, high = self.grid.bounds
        centre = np.zeros(3)
        centre[: self.map.dim] = (low + high) / 2
        extent = float(np.max(high - low))
        self.server.initial_camera.look_at = tuple(centre)
        self.server.initial_camera.position = tuple(centre + extent * np.array([-0.6, -0.8, 0.9]))

    def show_surface(self) -> None:
        """(Re)draw the surface at the slider's level, coloured as the dropdown says."""
        import trimesh

        vertices, faces = self.grid.mesh(self.level.value)
        self.n_faces = len(faces)
        if self.surface is not None:
            self.surface.remove()
            self.surface, self.mesh = None, None
        if len(faces) == 0:
            return
        if self.coloring.value == "height":
            colors = height_colors(vertices[:, 2], (vertices[:, 2].min(), vertices[:, 2].max()))
        else:
            _, std = self.map.occupancy(vertices, return_std=True)
            colors = height_colors(std, (0.0, max(float(std.max()), 1e-9)))
        self.mesh = trimesh.Trimesh(
            vertices, faces, vertex_colors=np.round(255 * colors).astype(np.uint8), process=False
        )
        self.surface = self.server.scene.add_mesh_trimesh("/surface", self.mesh)

    def show_slice_plane(self) -> None:
        """(Re)draw the horizontal slice of the occupancy at the slider's height, or hide it."""
        if not self.show_slice.value:
            self.server.scene.remove_by_name("/slice")
            return
        k = int(np.clip(
            (self.slice_height.value - self.grid.origin[2]) / self.grid.resolution,
            0, self.grid.shape[2] - 1,
        ))  # fmt: skip
        image = _heat_map(self.grid.probability[:, :, k])
        self._add_plane_image("/slice", image, self.grid.axis_centers(2)[k])

    def _show_plane(self) -> None:
        """A 2D map: its grid as an image on the plane z = 0."""
        self._add_plane_image("/grid", _heat_map(self.grid.probability), 0.0)

    def _add_plane_image(self, name: str, image: np.ndarray, z: float) -> None:
        """An (nx, ny, 3) image over the grid's x-y extent at height z, metres."""
        (x0, y0), (x1, y1) = self.grid.bounds[0][:2], self.grid.bounds[1][:2]
        self.server.scene.add_image(
            name,
            np.ascontiguousarray(np.transpose(image, (1, 0, 2))[::-1]),  # rows from +y down
            render_width=float(x1 - x0),
            render_height=float(y1 - y0),
            position=((x0 + x1) / 2, (y0 + y1) / 2, z),
        )

    def _show_samples(self) -> None:
        """The occupied samples the map keeps near surfaces, as points."""
        memory = self.map.memory_
        if memory is None or len(memory) == 0:
            return
        kept = np.arange(memory.points.shape[1]) < memory.filled[:, None]
        points = memory.points[memory.occupied & kept]
        if len(points):
            self.server.scene.add_point_cloud(
                "/samples", points.astype(np.float32), SAMPLE_COLOR, point_size=0.01,
                visible=False,
            )  # fmt: skip
            samples = self.server.gui.add_checkbox("show kept samples", False)

            @samples.on_update
            def _(_) -> None:
                self.server.scene.add_point_cloud(
                    "/samples", points.astype(np.float32), SAMPLE_COLOR, point_size=0.01,
                    visible=samples.value,
                )  # fmt: skip

    def _show_axes_and_path(self) -> None:
        """Axes at the origin (1 m long) and a grid of 1 m cells on the floor; the sensor path."""
        self.server.scene.add_frame("/axes", axes_length=1.0, axes_radius=0.02)
        low, high = self.grid.bounds[0], self.grid.bounds[1]
        self.server.scene.add_grid(
            "/metres",
            width=float(np.ceil(high[0] - low[0])),
            height=float(np.ceil(high[1] - low[1])),
            cell_size=1.0,
            position=((low[0] + high[0]) / 2, (low[1] + high[1]) / 2, float(low[-1]) if
                      self.map.dim == 3 else 0.0),
        )  # fmt: skip
        path = self.map.sensor_path
        if len(path) >= 2:
            path3 = path if path.shape[1] == 3 else np.column_stack([path, np.zeros(len(path))])
            segments = np.stack([path3[:-1], path3[1:]], axis=1).astype(np.float32)
            self.server.scene.add_line_segments("/sensor_path", segments, PATH_COLOR)


def viser_module():
    """The viser module; ImportError naming the extra to install where it is missing."""
    try:
        import viser
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error
    return viser


def _heat_map(probability: np.ndarray) -> np.ndarray:
    """(..., 3) uint8 RGB of occupancy probabilities: free blue, unknown white, occupied red."""
    import matplotlib

    return np.round(255 * matplotlib.colormaps["coolwarm"](probability)[..., :3]).astype(np.uint8)
