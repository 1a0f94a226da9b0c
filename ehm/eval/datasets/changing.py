"""A scene that changes while it is scanned, with its exact occupancy at every scan: a cart
that leaves, a crate that arrives and a person who walks across a room, seen by a LiDAR, a 2D
laser or a depth camera that moves through it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.eval.datasets.depth_camera import camera_directions, rotation_world_camera
from ehm.eval.datasets.scene import Scene, room_shell
from ehm.eval.datasets.simulated import lidar_directions, simulate_scan


@dataclass(frozen=True)
class Mover:
    """A solid box that is somewhere in some scans: boxes (n_scans, 2, d) float64, metres,
    world frame, its low and high corner at each scan, NaN where it is not in the scene.
    role: 'departs' (there at first, gone later), 'arrives' (absent at first, there later),
    'returns' (a departed mover back where it stood) or 'walks' (there in some scans, somewhere
    else in each)."""

    name: str
    role: str
    boxes: np.ndarray

    def present(self, scan: int) -> bool:
        """Whether the mover is in the scene at scan `scan`."""
        return bool(np.all(np.isfinite(self.boxes[scan])))


@dataclass(frozen=True)
class ChangingDataset:
    """Scans of a scene whose solids change between scans: static, the solids that never
    move; movers, the boxes that do (Mover); times (n_scans,) float64, seconds, when each scan
    was taken."""

    name: str
    scans: list[Scan]
    static: Scene
    movers: tuple[Mover, ...]
    times: np.ndarray

    def scene_at(self, scan: int) -> Scene:
        """The exact scene at scan `scan`: the static solids and the movers there."""
        return scene_at(self.static, self.movers, scan)

    def mover(self, role: str) -> Mover:
        """The first mover of `role`."""
        return next(m for m in self.movers if m.role == role)

    def has(self, role: str) -> bool:
        """Whether a mover of `role` is in the scene."""
        return any(m.role == role for m in self.movers)


def scene_at(static: Scene, movers: tuple[Mover, ...], scan: int) -> Scene:
    """The `static` solids and the boxes of the `movers` present at scan `scan`."""
    boxes = [m.boxes[scan] for m in movers if m.present(scan)]
    if not boxes:
        return static
    return Scene(
        np.vstack([static.box_min, [b[0] for b in boxes]]),
        np.vstack([static.box_max, [b[1] for b in boxes]]),
        static.ball_centres,
        static.ball_radii,
    )


def changing_room_scene() -> Scene:
    """The static part of the changing room: an 8 x 6 x 3 m room with a table, a cabinet and
    a shelf."""
    walls_min, walls_max = room_shell([-4.0, -3.0, 0.0], [4.0, 3.0, 3.0], thickness=0.2)
    furniture = [
        ([-1.0, -2.9, 0.72], [0.6, -2.1, 0.77]),  # table top along the south wall
        ([-1.0, -2.9, 0.0], [-0.94, -2.84, 0.72]),  # its legs
        ([0.54, -2.9, 0.0], [0.6, -2.84, 0.72]),
        ([-1.0, -2.16, 0.0], [-0.94, -2.1, 0.72]),
        ([0.54, -2.16, 0.0], [0.6, -2.1, 0.72]),
        ([-4.0, 1.0, 0.0], [-3.5, 2.6, 2.0]),  # cabinet on the west wall
        ([3.6, -2.0, 0.0], [4.0, 0.5, 1.8]),  # shelf on the east wall
    ]
    return Scene(
        np.vstack([walls_min, [f[0] for f in furniture]]),
        np.vstack([walls_max, [f[1] for f in furniture]]),
        np.zeros((0, 3)),
        np.zeros(0),
    )


def _boxes_where(
    n_scans: int, present: np.ndarray, low: np.ndarray, size: np.ndarray
) -> np.ndarray:
    """(n_scans, 2, 3) boxes of `size` (3,) with their low corners `low` (n_scans, 3) or (3,),
    NaN where not `present` (n_scans,) bool."""
    low = np.broadcast_to(np.asarray(low, dtype=np.float64), (n_scans, 3))
    boxes = np.stack([low, low + size], axis=1)
    boxes[~present] = np.nan
    return boxes


# The depth camera of changing_room: its pixels across and down, field of view across
# (degrees), tilt below the horizon (degrees) and range (metres), as a RealSense D435's.
DEPTH_PIXELS = (160, 120)
DEPTH_FOV = 87.0
DEPTH_PITCH = 15.0
DEPTH_RANGE = 6.0


def cut_at(scene: Scene, height: float) -> Scene:
    """The 2D scene a plane `height` metres up cuts from a 3D `scene`: the boxes it crosses,
    the discs it cuts from the balls."""
    crossed = (scene.box_min[:, 2] <= height) & (height <= scene.box_max[:, 2])
    rise = height - scene.ball_centres[:, 2]
    cut = np.abs(rise) < scene.ball_radii
    return Scene(
        scene.box_min[crossed, :2],
        scene.box_max[crossed, :2],
        scene.ball_centres[cut, :2],
        np.sqrt(scene.ball_radii[cut] ** 2 - rise[cut] ** 2),
    )


def _mover_cut_at(mover: Mover, height: float) -> Mover:
    """The 2D mover a plane `height` metres up cuts from a 3D `mover`: absent (NaN) in the
    scans where it does not reach the plane."""
    boxes = mover.boxes[:, :, :2].copy()
    with np.errstate(invalid="ignore"):
        crossed = (mover.boxes[:, 0, 2] <= height) & (height <= mover.boxes[:, 1, 2])
    boxes[~crossed] = np.nan
    return Mover(mover.name, mover.role, boxes)


def sensor_path(path: str, n_scans: int, height: float, laps: int = 1) -> np.ndarray:
    """(n_scans, 3) sensor positions, metres, of the changing room's `path` ('line' or
    'loop', `laps` times round; see changing_room) at `height`."""
    return _path_and_headings(path, n_scans, height, laps)[0]


def _path_and_headings(
    path: str, n_scans: int, height: float, laps: int
) -> tuple[np.ndarray, np.ndarray]:
    """sensor_path's positions (n_scans, 3) and the headings along them (n_scans,), radians
    from +x towards +y."""
    if laps < 1:
        raise ValueError(f"laps must be a whole number of times round, at least 1, got {laps!r}")
    if path == "line":
        x, y = np.linspace(-2.5, 2.5, n_scans), np.zeros(n_scans)
        headings = np.zeros(n_scans)
    elif path == "loop":
        turn = np.linspace(0.0, 2.0 * np.pi * laps, n_scans, endpoint=False)
        x, y = 2.6 * np.cos(turn), 0.5 * np.sin(turn)
        headings = np.arctan2(0.5 * np.cos(turn), -2.6 * np.sin(turn))
    else:
        raise ValueError(f"path must be 'line' or 'loop', got {path!r}")
    return np.column_stack([x, y, np.full(n_scans, height)]), headings


def _depth_frame(
    scene: Scene,
    origin: np.ndarray,
    directions: np.ndarray,
    noise_std: float,
    rng: np.random.Generator,
) -> Scan:
    """A depth camera's frame from `origin` along its pixels' `directions` (n, 3), world
    frame: pixels that see nothing within DEPTH_RANGE are left out, the others' ranges get
    Gaussian noise of `noise_std` times the square of the range (metres)."""
    ranges = scene.raycast(origin, directions)
    seen = ranges <= DEPTH_RANGE
    ranges = ranges[seen]
    ranges = ranges + rng.normal(0.0, 1.0, len(ranges)) * noise_std * ranges**2
    return Scan(origin + directions[seen] * ranges[:, None], origin)


def changing_room(
    seed: int = 0,
    n_scans: int = 14,
    rings: int = 64,
    azimuths: int = 1024,
    elevations: tuple[float, float] = (-45.0, 45.0),
    height: float = 1.2,
    path: str = "line",
    laps: int = 1,
    sensor: str = "lidar",
    cart: tuple[float, float, float] = (0.8, 0.6, 0.9),
    noise_std: float = 0.01,
    departs_at: int = 5,
    returns_at: int | None = None,
    arrives_at: int = 8,
    walk: tuple[int, int] = (2, 10),
    scan_period: float = 1.0,
) -> ChangingDataset:
    """`n_scans` scans of a `sensor` `height` metres up, one every `scan_period` seconds,
    moving along `path`: 'line', the room's x axis from -2.5 to 2.5 m; 'loop', `laps` times
    round an ellipse of half-axes 2.6 m (x) and 0.5 m (y) about the room's centre, as a robot
    patrols. sensor: 'lidar', a 3D LiDAR of rings x azimuths rays, rings evenly spaced between
    `elevations` (low, high) degrees, 20 m range; 'laser', a 2D laser of `azimuths` rays
    round, 20 m range, in the 2D room the plane at its height cuts from the 3D one (cut_at);
    'depth', a depth camera looking ahead along the path (DEPTH_PIXELS, DEPTH_FOV,
    DEPTH_PITCH, DEPTH_RANGE), whose range noise is `noise_std` times the square of the range.
    Meanwhile:

    - a cart (`cart`, its size along x, y and z, metres: 0.8 x 0.6 x 0.9 by default; south of
      the path, centred on x = 1 m, its north face at y = -0.8 m) stands there until scan
      `departs_at`, from which on it is gone, back where it stood from scan `returns_at` on
      (None: never; a mover of role 'returns');
    - a crate (0.6 x 0.6 x 0.6 m, north of the path) is there from scan `arrives_at` on;
    - a person (0.4 x 0.3 x 1.75 m) walks west to east along the north wall, 0.6 m a scan,
      in scans walk[0] to walk[1] - 1, and is gone before and after.
    """
    scans_index = np.arange(n_scans)
    cart_size = np.asarray(cart, dtype=np.float64)
    cart_low = [1.0 - cart_size[0] / 2, -0.8 - cart_size[1], 0.0]
    cart_boxes = _boxes_where(n_scans, scans_index < departs_at, cart_low, cart_size)
    crate = _boxes_where(
        n_scans, scans_index >= arrives_at, [-1.9, 0.8, 0.0], np.array([0.6, 0.6, 0.6])
    )
    walking = (scans_index >= walk[0]) & (scans_index < walk[1])
    walker_low = np.column_stack(
        [-3.0 + 0.6 * (scans_index - walk[0]), np.full(n_scans, 1.9), np.zeros(n_scans)]
    )
    walker = _boxes_where(n_scans, walking, walker_low, np.array([0.4, 0.3, 1.75]))
    movers = (
        Mover("cart", "departs", cart_boxes),
        Mover("crate", "arrives", crate),
        Mover("person", "walks", walker),
    )
    if returns_at is not None:
        if not departs_at < returns_at <= n_scans:
            raise ValueError(f"the cart returns after it departs, got {returns_at}")
        back = _boxes_where(n_scans, scans_index >= returns_at, cart_low, cart_size)
        movers += (Mover("cart back", "returns", back),)
    static = changing_room_scene()
    origins, headings = _path_and_headings(path, n_scans, height, laps)
    rng = np.random.default_rng(seed)
    if sensor == "laser":
        static = cut_at(static, height)
        movers = tuple(_mover_cut_at(mover, height) for mover in movers)
        angles = np.linspace(0.0, 2.0 * np.pi, azimuths, endpoint=False)
        directions, origins = np.column_stack([np.cos(angles), np.sin(angles)]), origins[:, :2]
    elif sensor == "lidar":
        directions = lidar_directions(rings, azimuths, elevations[1], elevations[0])
    elif sensor == "depth":
        pixels = camera_directions(*DEPTH_PIXELS, DEPTH_FOV)
    else:
        raise ValueError(f"sensor must be 'lidar', 'laser' or 'depth', got {sensor!r}")
    scans = []
    for i, (origin, heading) in enumerate(zip(origins, headings, strict=True)):
        scene = scene_at(static, movers, i)
        if sensor == "depth":
            directions = pixels @ rotation_world_camera(np.degrees(heading), DEPTH_PITCH).T
            scans.append(_depth_frame(scene, origin, directions, noise_std, rng))
        else:
            scans.append(simulate_scan(scene, origin, directions, 20.0, noise_std, rng))
    times = scan_period * scans_index.astype(np.float64)
    return ChangingDataset("changing_room", scans, static, movers, times)
