"""A map in the browser, served with viser (`pip install 'ehm[viewer]'`): for a 3D map its
surface at an occupancy level (a slider re-meshes it) coloured by height or by the occupancy's
standard deviation, a slider that leaves out the surface above a height (to look into rooms), a
horizontal slice of the occupancy, its std or the distance to obstacles as a heat map at a
chosen height, the occupied
samples the map keeps near surfaces (where its scans hit), the sensor path and axes in metres;
for a 2D map its grid as an image with the sensor path.

    viewer = MapViewer(hilbert_map, resolution=0.1, port=8080)   # http://localhost:8080
    viewer.level.value = 0.7                                     # what the slider does

Nothing else in the package imports this module.
"""

from __future__ import annotations

import shutil
import subprocess
import time
from os import PathLike

import numpy as np

from ehm.errors import InputError
from ehm.hilbert_map import HilbertMap
from ehm.pipeline import MappingRun, NullObserver
from ehm.viz.colors import height_colors

INSTALL_HINT = "the viewer needs viser: pip install 'ehm[viewer]'"
# What a slice can show.
SLICES = ("occupancy", "uncertainty (std)", "distance to obstacles")
# Colours of the sensor path and the surface samples, RGB 0-255.
PATH_COLOR = (230, 40, 40)
SAMPLE_COLOR = (40, 40, 40)


# Where the viewer first cuts the surface, metres above the sensor's median height.
CUT_ABOVE_SENSOR = 1.0


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
        cut_above: float | None = None,
    ) -> None:
        viser = viser_module()
        self.map = hilbert_map
        self.grid = hilbert_map.grid(resolution=resolution, std=hilbert_map.dim == 3)
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.surface = None
        self.mesh = None
        self.slice_image: np.ndarray | None = None  # (nx, ny, 3) uint8, the slice shown
        self.n_faces = 0
        self.samples = self.show_samples = None  # a map that keeps samples shows them
        self._aim_camera()
        self._show_axes_and_path()
        if hilbert_map.dim == 2:
            self._show_plane()
            return
        self.level = self.server.gui.add_slider("occupancy level", 0.05, 0.95, 0.05, 0.5)
        self.coloring = self.server.gui.add_dropdown(
            "colour by", ("height", "uncertainty (std)"), initial_value="height"
        )
        step = self.grid.resolution
        low, high = np.floor(self.grid.bounds[0][2] / step), np.ceil(self.grid.bounds[1][2] / step)
        # Multiples of the step, rounded to micrometres: 12 * 0.1 reads 1.2, not 1.2000000000000002.
        low, high = round(float(low * step), 6), round(float(high * step), 6)
        sensor = (
            float(np.median(hilbert_map.sensor_path[:, 2])) if len(hilbert_map.sensor_path) else low
        )

        def on_step(height: float) -> float:
            return round(float(np.clip(np.round(height / step) * step, low, high)), 6)

        self.slice_height = self.server.gui.add_slider(
            "slice height (m)", low, high, step, on_step(sensor)
        )
        # Cut below the ceiling: a room opens from above, a street keeps its trees' trunks.
        self.cut_above = self.server.gui.add_slider(
            "cut above (m)", low, high, step,
            on_step(sensor + CUT_ABOVE_SENSOR if cut_above is None else cut_above),
        )  # fmt: skip
        self.show_slice = self.server.gui.add_checkbox("show slice", False)
        self.slice_of = self.server.gui.add_dropdown("slice of", SLICES, initial_value=SLICES[0])
        self.level.on_update(lambda _: self.show_surface())
        self.coloring.on_update(lambda _: self.show_surface())
        self.cut_above.on_update(lambda _: self.show_surface())
        self.slice_height.on_update(lambda _: self.show_slice_plane())
        self.show_slice.on_update(lambda _: self.show_slice_plane())
        self.slice_of.on_update(lambda _: self.show_slice_plane())
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
        vertices, faces = self.grid.mesh(self.level.value)
        faces = faces[vertices[faces, 2].min(axis=1) <= self.cut_above.value]
        self.n_faces = len(faces)
        if self.surface is not None:
            self.surface.remove()
            self.surface, self.mesh = None, None
        if len(faces) == 0:
            return
        if self.coloring.value == "height":
            values = vertices[:, 2]
            span = (float(values.min()), float(values.max()))
        else:
            _, values = self.map.occupancy(vertices, return_std=True)
            span = (0.0, max(float(values.max()), 1e-9))
        self.mesh = colored_mesh(vertices, faces, values, span)
        self.surface = self.server.scene.add_mesh_trimesh("/surface", self.mesh)

    def show_slice_plane(self) -> None:
        """(Re)draw the horizontal slice at the slider's height, or hide it: the occupancy, its
        std, or the signed distance to obstacles (HilbertMap.distance) from inside them (red)
        through their surface (white) to distance_reach away (blue), on a square-root scale."""
        if not self.show_slice.value:
            self.server.scene.remove_by_name("/slice")
            self.slice_image = None
            return
        k = int(np.clip(
            (self.slice_height.value - self.grid.origin[2]) / self.grid.resolution,
            0, self.grid.shape[2] - 1,
        ))  # fmt: skip
        z = self.grid.axis_centers(2)[k]
        if self.slice_of.value == SLICES[0]:
            image = _heat_map(self.grid.probability[:, :, k])
        elif self.slice_of.value == SLICES[1]:  # from 0 (blue) to its largest (red)
            std = self.grid.std[:, :, k]
            image = _heat_map(std / max(float(self.grid.std.max()), 1e-9))
        else:
            x, y = np.meshgrid(self.grid.axis_centers(0), self.grid.axis_centers(1), indexing="ij")
            centres = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)])
            reach = self.map.config.distance_reach
            distance = self.map.distance(centres).reshape(x.shape) / reach
            # On a square-root scale, so the few centimetres inside thin walls show.
            image = _heat_map(0.5 - 0.5 * np.sign(distance) * np.sqrt(np.abs(distance)))
        self.slice_image = image
        add_plane_image(self.server, "/slice", self.grid, image, z)

    def _show_plane(self) -> None:
        """A 2D map: its grid as an image on the plane z = 0."""
        add_plane_image(self.server, "/grid", self.grid, _heat_map(self.grid.probability), 0.0)

    def _show_samples(self) -> None:
        """The occupied evidence the map keeps near surfaces (ehm.core.observations.memory), as
        points (a tiled map keeps it in its tiles, which the viewer does not read one by one)."""
        model = getattr(self.map, "model_", None)
        if model is None or len(model.memory) == 0:
            return
        evidence = model.memory.samples()
        points = evidence.points[evidence.occupied]
        if self.map.local_origin_ is not None:  # kept in the map's own frame
            points = points + self.map.local_origin_
        if len(points):
            self.samples = self.server.scene.add_point_cloud(
                "/samples", points.astype(np.float32), SAMPLE_COLOR, point_size=0.01,
                visible=False,
            )  # fmt: skip
            self.show_samples = self.server.gui.add_checkbox("show kept evidence", False)
            self.show_samples.on_update(
                lambda _: setattr(self.samples, "visible", self.show_samples.value)
            )

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
            self.server.scene.add_line_segments("/sensor_path", path_segments(path), PATH_COLOR)


def add_plane_image(server, name: str, grid, image: np.ndarray, z: float) -> None:
    """An (nx, ny, 3) image of a grid's cells over its x-y extent at height z, metres."""
    (x0, y0), (x1, y1) = grid.bounds[0][:2], grid.bounds[1][:2]
    server.scene.add_image(
        name,
        np.ascontiguousarray(np.transpose(image, (1, 0, 2))[::-1]),  # rows from +y down
        render_width=float(x1 - x0),
        render_height=float(y1 - y0),
        position=((x0 + x1) / 2, (y0 + y1) / 2, z),
    )


def browser_screenshot(
    url: str, path: str | PathLike[str], width: int = 1200, height: int = 800
) -> None:
    """Write a PNG of the page at `url` as headless Chromium draws it (Debian's chromium
    package, which `make test` installs; WebGL in software). Chromium's virtual time runs the
    page as fast as it can, up to 20 s of page time, then takes the picture."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise InputError("headless screenshots need Chromium: apt-get install chromium")
    subprocess.run(
        [chromium, "--headless=new", "--no-sandbox", "--hide-scrollbars",
         "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
         f"--window-size={width},{height}", "--virtual-time-budget=20000",
         f"--screenshot={path}", url],
        check=True, capture_output=True, timeout=180,
    )  # fmt: skip


def colored_mesh(vertices: np.ndarray, faces: np.ndarray, values: np.ndarray, span: tuple):
    """A trimesh.Trimesh of the surface, each vertex coloured by its value (n,) over `span`."""
    import trimesh

    colors = np.round(255 * height_colors(values, span)).astype(np.uint8)
    return trimesh.Trimesh(vertices, faces, vertex_colors=colors, process=False)


def path_segments(path: np.ndarray) -> np.ndarray:
    """(n - 1, 2, 3) float32 segments joining the (n, d) poses of a sensor path (z = 0 in 2D)."""
    if path.shape[1] == 2:
        path = np.column_stack([path, np.zeros(len(path))])
    return np.stack([path[:-1], path[1:]], axis=1).astype(np.float32)


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


class LiveView(NullObserver):
    """A pipeline observer (ehm.pipeline.MappingObserver) that shows a map growing in the
    browser: every `refresh_seconds` of mapping, once the map has learned its waiting scans,
    the surface is re-meshed from a fresh grid; the last scan's points and the sensor path
    are drawn, and a readout gives scans and scans per second. The refresh runs on the mapping
    thread, so it costs what re-meshing costs, `refresh_seconds` apart."""

    def __init__(
        self,
        resolution: float = 0.1,
        port: int = 8080,
        host: str = "127.0.0.1",
        refresh_seconds: float = 2.0,
        level: float = 0.5,
    ) -> None:
        viser = viser_module()
        self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.resolution, self.refresh_seconds, self.level = resolution, refresh_seconds, level
        self.refreshes = 0
        self._readout = self.server.gui.add_markdown("waiting for the first scan")
        self._last_refresh = 0.0
        self._start = 0.0
        self._scans = 0

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    @property
    def readout(self) -> str:
        """The text the page shows: scans so far, their rate, the clusters."""
        return self._readout.content

    def started(self, total: int | None) -> None:
        self._start = self._last_refresh = time.perf_counter()
        self.server.scene.add_frame("/axes", axes_length=1.0, axes_radius=0.02)

    def scan_learned(self, index: int, scan, hilbert_map: HilbertMap) -> None:
        self._scans = index + 1
        now = time.perf_counter()
        if now - self._last_refresh >= self.refresh_seconds and hilbert_map.n_waiting_scans == 0:
            self.refresh(hilbert_map, scan)
            self._last_refresh = time.perf_counter()

    def finished(self, run: MappingRun) -> None:
        if run.n_scans:
            self.refresh(run.hilbert_map, None)

    def refresh(self, hilbert_map: HilbertMap, scan) -> None:
        """Draw the map as it stands (and `scan`'s points, if given)."""
        self.refreshes += 1
        seconds = max(time.perf_counter() - self._start, 1e-9)
        self._readout.content = (
            f"**{self._scans} scans**, {self._scans / seconds:.1f} scans/s, "
            f"{hilbert_map.n_clusters} clusters"
        )
        if hilbert_map.n_clusters == 0:
            return
        grid = hilbert_map.grid(resolution=self.resolution)
        if hilbert_map.dim == 3:
            vertices, faces = grid.mesh(self.level)
            if len(faces):
                z = vertices[:, 2]
                mesh = colored_mesh(vertices, faces, z, (float(z.min()), float(z.max())))
                self.server.scene.add_mesh_trimesh("/surface", mesh)
        else:
            add_plane_image(self.server, "/grid", grid, _heat_map(grid.probability), 0.0)
        path = hilbert_map.sensor_path
        if len(path) >= 2:
            self.server.scene.add_line_segments("/sensor_path", path_segments(path), PATH_COLOR)
        if scan is not None:
            points = scan.points_world[scan.hit_mask][:: max(len(scan) // 20_000, 1)]
            if points.shape[1] == 2:
                points = np.column_stack([points, np.zeros(len(points))])
            self.server.scene.add_point_cloud(
                "/current_scan", points.astype(np.float32), (255, 150, 0), point_size=0.03
            )
