"""An outdoor scene where surfaces are thin, sloped or porous: a road between a grassy hillside
and a fenced verge, seen by a 64-ring LiDAR driven along it (3D, exact occupancy).

What it holds that the street (ehm.eval.datasets.simulated) does not:
- ground that rises: a hillside of 12 degrees (steps of 2 cm, below the range noise), seen
  from below at grazing angles that change along it;
- kerbs 12 cm high, and a fence of 6 cm posts and 4 cm rails;
- poles 5 and 8 cm thick standing on the slope 10-25 m from the road;
- vegetation: bushes and tree crowns made of small balls with gaps between them, which some
  rays pass and others stop in.

Deterministic for a seed: the seed draws the range noise; the scene itself never changes.
"""

from __future__ import annotations

import numpy as np

from ehm.eval.datasets.scene import Scene
from ehm.eval.datasets.simulated import (
    SimulatedDataset,
    lidar_directions,
    lidar_drive,
    scene_of,
)

# The road runs along x, its kerbs' inner faces at y = +-ROAD_HALF_WIDTH, metres.
ROAD_HALF_WIDTH = 4.0
ROAD_LENGTH = 70.0
# The hillside rises from the north kerb at SLOPE_DEGREES, in steps of STEP_RISE metres.
SLOPE_DEGREES = 12.0
STEP_RISE = 0.02
HILL_DEPTH = 20.0
KERB_HEIGHT, KERB_WIDTH = 0.12, 0.3
# Where the hillside begins (the north kerb's outer edge), and the run of each of its steps.
HILL_FOOT = ROAD_HALF_WIDTH + KERB_WIDTH
STEP_RUN = STEP_RISE / np.tan(np.radians(SLOPE_DEGREES))
FENCE_Y = -8.0
# The scene's own draws (the balls of bushes and crowns), fixed: only range noise follows a seed.
_SCENE_SEED = 7


def hill_height(y: np.ndarray | float) -> np.ndarray:
    """The hillside's surface height, metres, at distance y north of the road's axis (0 on and
    south of the north kerb's outer edge), as its steps make it."""
    steps = np.floor((np.asarray(y, dtype=np.float64) - HILL_FOOT) / STEP_RUN) + 1
    return np.clip(steps, 0, np.floor(HILL_DEPTH / STEP_RUN)) * STEP_RISE


def _hillside_boxes() -> list[tuple[list[float], list[float]]]:
    """The hillside's steps: columns of ground, each one STEP_RISE higher than the last."""
    half = ROAD_LENGTH / 2
    return [
        (
            [-half, HILL_FOOT + i * STEP_RUN, 0.0],
            [half, HILL_FOOT + (i + 1) * STEP_RUN, (i + 1) * STEP_RISE],
        )
        for i in range(int(HILL_DEPTH / STEP_RUN))
    ]


def _clustered_balls(
    rng: np.random.Generator, centre: np.ndarray, spread: np.ndarray, count: int, radii: tuple
) -> tuple[np.ndarray, np.ndarray]:
    """`count` balls of radii uniform in `radii`, metres, their centres uniform in the ellipsoid
    of semi-axes `spread` (3,) around `centre` (3,): foliage with gaps between leaves."""
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    offsets = directions * rng.random((count, 1)) ** (1 / 3) * spread
    return centre + offsets, rng.uniform(*radii, count)


def hillside_scene() -> Scene:
    """The road, its kerbs, the hillside with its poles and trees, the fence and the bushes of
    the south verge (see the module docstring)."""
    half = ROAD_LENGTH / 2
    boxes = [
        ([-half, -25.0, -0.5], [half, 25.0, 0.0]),  # ground under everything
        ([-half, ROAD_HALF_WIDTH, 0.0], [half, HILL_FOOT, KERB_HEIGHT]),
        ([-half, -HILL_FOOT, 0.0], [half, -ROAD_HALF_WIDTH, KERB_HEIGHT]),
        *_hillside_boxes(),
    ]
    for x, y, width in ((-20.0, 14.0, 0.08), (-6.0, 19.0, 0.05), (8.0, 24.0, 0.08),
                        (22.0, 16.0, 0.05), (30.0, 12.0, 0.08)):  # fmt: skip
        base = float(hill_height(y))  # each stands 5 cm deep in the slope
        low, high = [x - width / 2, y - width / 2, base - 0.05], [x + width / 2, y + width / 2]
        boxes.append((low, [*high, base + 4.0]))
    for x in np.arange(-half + 1.0, half, 3.0):  # fence posts
        boxes.append(([x - 0.03, FENCE_Y - 0.03, 0.0], [x + 0.03, FENCE_Y + 0.03, 1.2]))
    for z in (0.5, 1.0):  # fence rails
        boxes.append(([-half, FENCE_Y - 0.02, z - 0.02], [half, FENCE_Y + 0.02, z + 0.02]))
    rng = np.random.default_rng(_SCENE_SEED)
    centres, radii = [], []
    for x, y in ((-25.0, 9.0), (-10.0, 13.0), (5.0, 10.0), (20.0, 21.0)):  # trees on the slope
        base = float(hill_height(y))
        boxes.append(([x - 0.12, y - 0.12, 0.0], [x + 0.12, y + 0.12, base + 3.0]))
        crown = _clustered_balls(rng, np.array([x, y, base + 4.5]), np.array([2.0, 2.0, 1.6]),
                                 70, (0.15, 0.35))  # fmt: skip
        centres.append(crown[0])
        radii.append(crown[1])
    for x in np.arange(-30.0, 31.0, 6.0):  # bushes on the south verge
        bush = _clustered_balls(rng, np.array([x, -6.2, 0.4]), np.array([0.8, 0.6, 0.4]),
                                12, (0.1, 0.25))  # fmt: skip
        centres.append(bush[0])
        radii.append(bush[1])
    return scene_of(boxes, np.concatenate(centres), np.concatenate(radii))


def hillside(
    seed: int = 0,
    rings: int = 64,
    azimuths: int = 1024,
    noise_std: float = 0.02,
    max_range: float = 40.0,
) -> SimulatedDataset:
    """Four scans of a 64-ring LiDAR (rings x azimuths rays, 65,536 by default; elevations -25
    to +15 degrees, 1.8 m up, `max_range` metres) 10 m apart along the road: for maps of 0.1
    m."""
    directions = lidar_directions(rings, azimuths, 15.0, -25.0)
    stops = (-15.0, -5.0, 5.0, 15.0)
    return lidar_drive(
        "hillside", hillside_scene(), directions, stops, 0.0, max_range, noise_std, seed
    )
