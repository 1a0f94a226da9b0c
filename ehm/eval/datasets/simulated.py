"""Embedded synthetic scenes with exact occupancy: the virtual room, a warehouse and an outdoor
street seen by two LiDARs (3D), and a floor plan and a 100 m office corridor (2D).

All are deterministic for a seed; the seed only draws the range noise.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.eval.datasets.scene import Scene, room_shell


@dataclass(frozen=True)
class SimulatedDataset:
    """Scans simulated in a scene whose exact occupancy is known."""

    name: str
    scans: list[Scan]
    scene: Scene


def simulate_scan(
    scene: Scene,
    origin: np.ndarray,
    directions: np.ndarray,
    max_range: float,
    noise_std: float,
    rng: np.random.Generator,
) -> Scan:
    """One scan from `origin` along unit `directions` (n, d): ranges with Gaussian noise of
    `noise_std` metres; rays that hit nothing within `max_range` are kept as no-return rays
    ending at max_range."""
    ranges = scene.raycast(origin, directions)
    hit = ranges <= max_range
    ranges = np.where(hit, ranges + rng.normal(0.0, noise_std, len(ranges)), max_range)
    return Scan(origin + directions * ranges[:, None], origin, hit)


def lidar_directions(
    rings: int, azimuths: int, max_elevation_deg: float, min_elevation_deg: float | None = None
) -> np.ndarray:
    """(rings * azimuths, 3) unit ray directions of a spinning LiDAR: rings evenly spaced
    from min_elevation_deg (default -max_elevation_deg) to max_elevation_deg, azimuths evenly
    spaced round."""
    low = -max_elevation_deg if min_elevation_deg is None else min_elevation_deg
    elevation = np.deg2rad(np.linspace(low, max_elevation_deg, rings))
    azimuth = np.linspace(0.0, 2.0 * np.pi, azimuths, endpoint=False)
    el, az = np.meshgrid(elevation, azimuth, indexing="ij")
    return np.column_stack(
        [(np.cos(el) * np.cos(az)).ravel(), (np.cos(el) * np.sin(az)).ravel(), np.sin(el).ravel()]
    )


def virtual_room_scene() -> Scene:
    """An 8 x 6 x 3 m room with a table, a sofa, a cabinet, a crate and two balls."""
    walls_min, walls_max = room_shell([-4.0, -3.0, 0.0], [4.0, 3.0, 3.0], thickness=0.2)
    furniture = [
        ([0.8, 0.6, 0.72], [2.4, 1.5, 0.77]),  # table top
        ([0.8, 0.6, 0.0], [0.86, 0.66, 0.72]),  # table legs
        ([2.34, 0.6, 0.0], [2.4, 0.66, 0.72]),
        ([0.8, 1.44, 0.0], [0.86, 1.5, 0.72]),
        ([2.34, 1.44, 0.0], [2.4, 1.5, 0.72]),
        ([-1.5, -3.0, 0.0], [0.5, -2.1, 0.45]),  # sofa seat
        ([-1.5, -3.0, 0.0], [0.5, -2.75, 0.9]),  # sofa back
        ([-4.0, 1.2, 0.0], [-3.5, 2.8, 2.0]),  # cabinet
        ([2.5, -2.0, 0.0], [3.2, -1.3, 0.6]),  # crate
    ]
    box_min = np.vstack([walls_min, [f[0] for f in furniture]])
    box_max = np.vstack([walls_max, [f[1] for f in furniture]])
    balls = np.array([[-2.0, 0.5, 0.35], [2.85, -1.65, 0.85]])
    return Scene(box_min, box_max, balls, np.array([0.35, 0.25]))


def virtual_room(
    seed: int = 0, rings: int = 64, azimuths: int = 1406, noise_std: float = 0.01
) -> SimulatedDataset:
    """One simulated 3D LiDAR scan (rings x azimuths rays, about 90,000 by default) from
    (0, 0, 1.2) m in the virtual room, elevations -55 to +55 degrees."""
    directions = lidar_directions(rings, azimuths, 55.0)
    scene = virtual_room_scene()
    rng = np.random.default_rng(seed)
    scan = simulate_scan(scene, np.array([0.0, 0.0, 1.2]), directions, 30.0, noise_std, rng)
    return SimulatedDataset("virtual_room", [scan], scene)


def warehouse_scene() -> Scene:
    """A 40 x 24 x 8 m hall: six rows of 2 m shelving, a mezzanine deck, pillars, crates."""
    walls_min, walls_max = room_shell([-20.0, -12.0, 0.0], [20.0, 12.0, 8.0], thickness=0.3)
    solids = []
    for row in range(6):  # shelving rows along x, each broken by an aisle in the middle
        y = -9.0 + 3.2 * row
        solids += [([-16.0, y, 0.0], [-2.0, y + 1.0, 2.0]), ([2.0, y, 0.0], [16.0, y + 1.0, 2.0])]
    for x in (-12.0, -4.0, 4.0, 12.0):  # pillars between rows and walls
        for y in (-11.0, 10.6):
            solids.append(([x, y, 0.0], [x + 0.4, y + 0.4, 8.0]))
    solids += [
        ([-20.0, -12.0, 4.0], [-17.0, 12.0, 4.2]),  # mezzanine deck along the west wall
        ([17.5, -6.0, 0.0], [19.0, -4.5, 1.2]),  # crates by the east wall
        ([17.5, 3.0, 0.0], [18.7, 4.2, 0.9]),
    ]
    box_min = np.vstack([walls_min, [b[0] for b in solids]])
    box_max = np.vstack([walls_max, [b[1] for b in solids]])
    balls = np.array([[0.0, 0.0, 0.6], [-18.0, 0.0, 4.8]])
    return Scene(box_min, box_max, balls, np.array([0.6, 0.5]))


def warehouse(
    seed: int = 0, rings: int = 64, azimuths: int = 1406, noise_std: float = 0.01
) -> SimulatedDataset:
    """Six simulated LiDAR scans (rings x azimuths rays each, elevations -30 to +30 degrees,
    50 m range) from 1.5 m up along the aisles of the warehouse: several times the virtual
    room's extent, for measuring search and memory in large maps."""
    directions = lidar_directions(rings, azimuths, 30.0)
    scene = warehouse_scene()
    rng = np.random.default_rng(seed)
    poses = np.array(
        [[-17.5, -10.0], [-8.0, -6.6], [0.0, -1.7], [8.0, 2.7], [17.0, 4.7], [0.0, 10.5]]
    )
    scans = [
        simulate_scan(scene, np.array([x, y, 1.5]), directions, 50.0, noise_std, rng)
        for x, y in poses
    ]
    return SimulatedDataset("warehouse", scans, scene)


def warehouse_drive(
    seed: int = 0,
    n_scans: int = 200,
    loops: int = 2,
    rings: int = 16,
    azimuths: int = 512,
    noise_std: float = 0.01,
) -> SimulatedDataset:
    """`n_scans` scans of a 16-ring LiDAR (rings x azimuths rays, elevations -15 to +15
    degrees, 30 m range) 1.5 m up, evenly spaced along `loops` laps of a loop round the
    warehouse's shelving (x = +-17 m, y = -10.3 and 9.5 m): a long 3D run that sees new parts
    of the hall on its first lap and the same ones again after."""
    corners = np.array([[-17.0, -10.3], [17.0, -10.3], [17.0, 9.5], [-17.0, 9.5], [-17.0, -10.3]])
    legs = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    along = np.linspace(0.0, loops * legs.sum(), n_scans, endpoint=False) % legs.sum()
    poses = np.column_stack(
        [np.interp(along, np.r_[0.0, np.cumsum(legs)], corners[:, axis]) for axis in (0, 1)]
    )
    directions = lidar_directions(rings, azimuths, 15.0)
    scene = warehouse_scene()
    rng = np.random.default_rng(seed)
    scans = [
        simulate_scan(scene, np.array([x, y, 1.5]), directions, 30.0, noise_std, rng)
        for x, y in poses
    ]
    return SimulatedDataset("warehouse_drive", scans, scene)


# The street's buildings along each side: (x from, x to, height), metres; 10 m deep.
NORTH_BUILDINGS = ((-60.0, -38.0, 12.0), (-35.0, -15.0, 9.0), (-12.0, 10.0, 15.0),
                   (13.0, 35.0, 7.0), (38.0, 60.0, 11.0))  # fmt: skip
SOUTH_BUILDINGS = ((-60.0, -42.0, 8.0), (-39.0, -20.0, 14.0), (-17.0, -2.0, 10.0),
                   (1.0, 22.0, 12.0), (25.0, 60.0, 9.0))  # fmt: skip


def street_scene() -> Scene:
    """A 120 m street between two rows of buildings (facades 8 m either side of its axis,
    7-15 m tall, with 3 m gaps), raised 15 cm sidewalks, lamp posts 8 cm thick and 6 m tall,
    sign posts 5 cm thick and 2.5 m tall, trees (30 cm trunks, crowns of 2 m radius) and
    parked cars, on flat ground (z = 0) that a LiDAR sees at grazing angles."""
    solids = [([-80.0, -30.0, -0.5], [80.0, 30.0, 0.0])]  # ground
    solids += [([-80.0, 6.0, 0.0], [80.0, 8.0, 0.15]), ([-80.0, -8.0, 0.0], [80.0, -6.0, 0.15])]
    for side, buildings in ((1.0, NORTH_BUILDINGS), (-1.0, SOUTH_BUILDINGS)):
        for x0, x1, height in buildings:
            y0, y1 = sorted((side * 8.0, side * 18.0))
            solids.append(([x0, y0, 0.0], [x1, y1, height]))
    for x in np.arange(-54.0, 55.0, 12.0):  # lamp posts on both sidewalks
        for y in (-6.6, 6.6):
            solids.append(([x - 0.04, y - 0.04, 0.0], [x + 0.04, y + 0.04, 6.0]))
    for x in (-45.0, -15.0, 15.0, 45.0):  # sign posts
        solids.append(([x - 0.025, -6.3, 0.0], [x + 0.025, -6.25, 2.5]))
    trees = [(x, y) for x in (-48.0, -24.0, 0.0, 24.0, 48.0) for y in (-7.0, 7.0)]
    for x, y in trees:
        solids.append(([x - 0.15, y - 0.15, 0.0], [x + 0.15, y + 0.15, 3.0]))
    for x in (-36.0, -8.0, 5.0, 30.0):  # parked cars in the north lane
        solids.append(([x, 4.0, 0.0], [x + 4.4, 5.8, 1.5]))
    return scene_of(solids, [(x, y, 4.8) for x, y in trees], 2.0)


def street(
    seed: int = 0,
    rings: int = 32,
    azimuths: int = 1024,
    noise_std: float = 0.02,
    max_range: float = 40.0,
) -> SimulatedDataset:
    """Six scans of a 32-ring LiDAR (rings x azimuths rays, elevations -25 to +10 degrees, 1.8
    m up, `max_range` metres) driven 50 m down the street's south lane, a scan every 10 m:
    ground seen at grazing angles out to 30 m and more, facades, thin poles and tree crowns."""
    directions = lidar_directions(rings, azimuths, 10.0, -25.0)
    stops = np.arange(-25.0, 26.0, 10.0)
    return _street_drive("street", directions, stops, max_range, noise_std, seed)


def outdoor_lidar(
    seed: int = 0,
    rings: int = 64,
    azimuths: int = 1563,
    noise_std: float = 0.02,
    max_range: float = 30.0,
) -> SimulatedDataset:
    """Three scans of a 64-ring LiDAR (rings x azimuths rays, about 100,000; elevations -25
    to +15 degrees, 1.8 m up, `max_range` metres) 15 m apart down the street's south lane: a
    long-range outdoor scene for maps of 0.1 m."""
    directions = lidar_directions(rings, azimuths, 15.0, -25.0)
    stops = np.array([-15.0, 0.0, 15.0])
    return _street_drive("outdoor_lidar", directions, stops, max_range, noise_std, seed)


def _street_drive(
    name: str,
    directions: np.ndarray,
    stops: np.ndarray,
    max_range: float,
    noise_std: float,
    seed: int,
) -> SimulatedDataset:
    """Scans of the street scene along unit `directions` (n, 3), one at each x of `stops`,
    metres, in the south lane 1.8 m up."""
    return lidar_drive(name, street_scene(), directions, stops, -2.0, max_range, noise_std, seed)


def lidar_drive(
    name: str,
    scene: Scene,
    directions: np.ndarray,
    stops: Sequence[float],
    lane_y: float,
    max_range: float,
    noise_std: float,
    seed: int,
) -> SimulatedDataset:
    """Scans of `scene` along unit `directions` (n, 3), one at each x of `stops`, metres, at
    y = `lane_y`, 1.8 m up, `max_range` metres, range noise of `noise_std` metres drawn from
    `seed`."""
    rng = np.random.default_rng(seed)
    scans = [
        simulate_scan(scene, np.array([x, lane_y, 1.8]), directions, max_range, noise_std, rng)
        for x in stops
    ]
    return SimulatedDataset(name, scans, scene)


def floor_plan_scene() -> Scene:
    """A 12 x 8 m 2D floor plan: two rooms joined by a door, pillars and a table."""
    walls_min, walls_max = room_shell([-6.0, -4.0], [6.0, 4.0], thickness=0.2)
    inner = [
        ([-0.1, -4.0], [0.1, -1.0]),  # dividing wall, door between y = -1 and 0.5
        ([-0.1, 0.5], [0.1, 4.0]),
        ([2.0, 1.5], [3.5, 2.5]),  # table
        ([-5.0, -3.5], [-3.5, -3.0]),  # shelf
    ]
    box_min = np.vstack([walls_min, [b[0] for b in inner]])
    box_max = np.vstack([walls_max, [b[1] for b in inner]])
    balls = np.array([[-3.0, 1.5], [3.5, -2.0]])
    return Scene(box_min, box_max, balls, np.array([0.4, 0.3]))


def floor_plan_2d(
    seed: int = 0, beams: int = 360, max_range: float = 8.0, noise_std: float = 0.01
) -> SimulatedDataset:
    """Five 2D laser scans of `beams` rays along a path through the floor plan; rays longer
    than `max_range` metres are no-return rays."""
    angles = np.linspace(0.0, 2.0 * np.pi, beams, endpoint=False)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    poses = np.array([[-3.0, -1.5], [-1.5, -0.2], [1.5, -0.2], [4.0, 0.5], [4.5, -2.8]])
    scene = floor_plan_scene()
    rng = np.random.default_rng(seed)
    scans = [simulate_scan(scene, p, directions, max_range, noise_std, rng) for p in poses]
    return SimulatedDataset("floor_plan_2d", scans, scene)


def corridor_scene(length: float = 100.0) -> Scene:
    """A 2D office floor `length` metres long: a 2 m corridor along x with 5 x 4 m rooms on
    both sides, each with a 1 m door onto the corridor and a piece of furniture, and a pillar
    in the corridor every 10 m. The layout is fixed."""
    n_rooms = int(length // 5.0)
    wall = 0.1
    layout = np.random.default_rng(7)
    boxes = [
        ([-wall, -5.0 - wall], [0.0, 5.0 + wall]),  # the two ends
        ([5.0 * n_rooms, -5.0 - wall], [5.0 * n_rooms + wall, 5.0 + wall]),
        ([-wall, -5.0 - wall], [5.0 * n_rooms + wall, -5.0]),  # the back walls of the rooms
        ([-wall, 5.0], [5.0 * n_rooms + wall, 5.0 + wall]),
    ]
    for room in range(n_rooms):
        x0 = 5.0 * room
        for side in (-1.0, 1.0):
            inner, outer = sorted((side * 1.0, side * (1.0 + wall)))
            boxes.append(([x0, inner], [x0 + 2.0, outer]))  # corridor wall, door from 2 to 3 m
            boxes.append(([x0 + 3.0, inner], [x0 + 5.0, outer]))
            near, far = sorted((side * 1.0, side * 5.0))
            boxes.append(([x0 + 5.0 - wall / 2, near], [x0 + 5.0 + wall / 2, far]))
            size = layout.uniform([0.5, 0.4], [1.5, 1.0])
            corner = [x0 + layout.uniform(0.3, 4.7 - size[0]), side * 4.7 - (side > 0) * size[1]]
            boxes.append((corner, [corner[0] + size[0], corner[1] + size[1]]))
    pillars = np.array([[10.0 * k + 5.0, 0.6] for k in range(int(length // 10.0))])
    return Scene(
        np.array([b[0] for b in boxes], dtype=np.float64),
        np.array([b[1] for b in boxes], dtype=np.float64),
        pillars.reshape(-1, 2),
        np.full(len(pillars), 0.15),
    )


def corridor_2d(
    seed: int = 0,
    n_scans: int = 2000,
    length: float = 100.0,
    beams: int = 180,
    max_range: float = 8.0,
    noise_std: float = 0.01,
) -> SimulatedDataset:
    """`n_scans` 2D laser scans of `beams` rays taken along the corridor of
    `corridor_scene(length)`, evenly spaced from one end to the other and weaving across it: a
    long run whose map keeps growing. Rays longer than `max_range` metres are no-return rays."""
    scene = corridor_scene(length)
    angles = np.linspace(0.0, 2.0 * np.pi, beams, endpoint=False)
    directions = np.column_stack([np.cos(angles), np.sin(angles)])
    x = np.linspace(0.5, 5.0 * int(length // 5.0) - 0.5, n_scans)
    poses = np.column_stack([x, 0.3 * np.sin(x / 3.0)])
    rng = np.random.default_rng(seed)
    scans = []
    for pose in poses:
        local = solids_in_range(scene, pose, max_range)
        scans.append(simulate_scan(local, pose, directions, max_range, noise_std, rng))
    return SimulatedDataset("corridor_2d", scans, scene)


def scene_of(boxes: list, balls: list | np.ndarray, radius: float | np.ndarray) -> Scene:
    """A 3D Scene of boxes ([low corner], [high corner]) and balls (x, y, z), metres, of one
    radius or (len(balls),) radii each."""
    return Scene(
        np.array([box[0] for box in boxes], dtype=np.float64),
        np.array([box[1] for box in boxes], dtype=np.float64),
        np.array(balls, dtype=np.float64).reshape(-1, 3),
        np.broadcast_to(np.asarray(radius, dtype=np.float64), len(balls)).copy(),
    )


def solids_in_range(scene: Scene, origin: np.ndarray, max_range: float) -> Scene:
    """The solids of `scene` within `max_range` metres of `origin`: the only ones a scan from
    there can hit, so ray-casting against them alone gives the same ranges, faster."""
    gap = np.maximum(np.maximum(scene.box_min - origin, origin - scene.box_max), 0.0)
    near = np.linalg.norm(gap, axis=1) <= max_range
    balls = np.linalg.norm(scene.ball_centres - origin, axis=1) <= max_range + scene.ball_radii
    return Scene(
        scene.box_min[near], scene.box_max[near], scene.ball_centres[balls], scene.ball_radii[balls]
    )


def city_scene(length: float = 1000.0, seed: int = 0) -> Scene:
    """A straight city street `length` metres long along +x: ground in 50 m tiles, buildings
    8-30 m tall in blocks of 60-100 m on both sides (facades 9 m from the axis), cross streets
    14 m wide between blocks, lamp posts every 25 m and trees every 40 m on the sidewalks."""
    rng = np.random.default_rng(seed)
    solids = []
    for x in np.arange(0.0, length, 50.0):  # ground tiles, so scans see only those near
        solids.append(([x, -60.0, -0.5], [x + 50.0, 60.0, 0.0]))
    for side in (1.0, -1.0):
        x = 0.0
        while x < length:
            block = rng.uniform(60.0, 100.0)
            for start in np.arange(x, min(x + block, length), 20.0):
                end = min(start + rng.uniform(14.0, 20.0), x + block, length)
                y0, y1 = sorted((side * 9.0, side * 24.0))
                solids.append(([start, y0, 0.0], [end, y1, rng.uniform(8.0, 30.0)]))
            x += block + 14.0  # a cross street
        for x in np.arange(12.5, length, 25.0):  # lamp posts
            y = side * 7.5
            solids.append(([x - 0.05, y - 0.05, 0.0], [x + 0.05, y + 0.05, 6.0]))
    trees = [(x, side * 7.0) for x in np.arange(20.0, length, 40.0) for side in (1.0, -1.0)]
    for x, y in trees:
        solids.append(([x - 0.15, y - 0.15, 0.0], [x + 0.15, y + 0.15, 3.0]))
    return scene_of(solids, [(x, y, 4.5) for x, y in trees], 1.8)


class CityDrive:
    """The scans of a drive down the right lane of `city_scene(length, seed)`: `n_scans`
    scans of a 16-ring LiDAR (rings x azimuths rays, elevations -15 to +10 degrees, 1.8 m up,
    `max_range` metres) evenly spaced along it, each made when it is read (ray-cast against
    the solids in range), so any one can be made alone: a large scene for tiled maps, in a
    few bytes that processes of a cluster each read from (a scan source, ehm.tiles)."""

    def __init__(
        self,
        seed: int = 0,
        length: float = 1000.0,
        n_scans: int = 1000,
        rings: int = 16,
        azimuths: int = 512,
        noise_std: float = 0.02,
        max_range: float = 40.0,
    ) -> None:
        self.seed, self.length, self.n_scans = seed, length, n_scans
        self.rings, self.azimuths = rings, azimuths
        self.noise_std, self.max_range = noise_std, max_range
        self._scene: Scene | None = None

    @property
    def scene(self) -> Scene:
        """The city, made on first use (each process that reads scans makes its own)."""
        if self._scene is None:
            self._scene = city_scene(self.length, self.seed)
        return self._scene

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_scene": None}

    def count(self) -> int:
        return self.n_scans

    def __len__(self) -> int:
        return self.n_scans

    def __iter__(self) -> Iterator[Scan]:
        return (scan for _, scan in self.read())

    def read(self, indices: Iterable[int] | None = None) -> Iterator[tuple[int, Scan]]:
        """(index, scan) for each of `indices` (None: every scan), ascending; scan i is the
        same whenever it is made."""
        directions = lidar_directions(self.rings, self.azimuths, 10.0, -15.0)
        stations = np.linspace(1.0, self.length - 1.0, self.n_scans)
        chosen = range(self.n_scans) if indices is None else sorted(set(indices))
        for i in chosen:
            origin = np.array([stations[i], -2.0, 1.8])
            local = solids_in_range(self.scene, origin, self.max_range)
            rng = np.random.default_rng([self.seed, i])
            yield i, simulate_scan(local, origin, directions, self.max_range, self.noise_std, rng)


def city_drive(
    seed: int = 0,
    length: float = 1000.0,
    n_scans: int = 1000,
    rings: int = 16,
    azimuths: int = 512,
    noise_std: float = 0.02,
    max_range: float = 40.0,
) -> SimulatedDataset:
    """All the scans of a CityDrive (see there), made now, with its scene."""
    drive = CityDrive(seed, length, n_scans, rings, azimuths, noise_std, max_range)
    return SimulatedDataset("city_drive", list(drive), drive.scene)
