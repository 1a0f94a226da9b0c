"""A road under overhead lines: wires thin across two axes, seen from below by a LiDAR (3D,
exact occupancy).

What it holds that the street and the hillside do not:
- conductors 1.5 cm across and a cable 3 cm across, 6-8 m up, running along the road and
  one crossing it: long in one direction, thinner than a map's voxel in the other two;
- wooden poles 20 cm across with crossarms, and house fronts across the road.

A LiDAR's rings spread with range and a wire's hits come a few to a ring: a scan sees each
wire in short runs of hits far apart, and the rays of the rings above and below it pass it
closely. Deterministic for a seed: the seed draws the range noise.
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

# The line runs along x at y = LINE_Y, metres; its poles stand POLE_SPACING apart.
LINE_Y = 7.0
LINE_LENGTH = 80.0
POLE_SPACING = 20.0
POLE_HEIGHT = 8.5
# Conductors on the crossarms (y offsets from the line, height) and the cable below them.
CONDUCTORS = ((-0.7, 8.2), (0.0, 8.2), (0.7, 8.2))
CONDUCTOR_WIDTH = 0.015
CABLE_HEIGHT, CABLE_WIDTH = 6.5, 0.03
# A service wire crossing the road from the line to the house fronts, CROSSING_HEIGHT up.
CROSSING_X, CROSSING_HEIGHT = 5.0, 5.5
HOUSE_FRONT_Y = -12.0


def _wire(
    low: list[float], high: list[float], width: float, axis: int
) -> tuple[list[float], list[float]]:
    """A box `width` across, its centre line from `low` to `high` along `axis`."""
    lo, hi = np.array(low, dtype=float) - width / 2, np.array(high, dtype=float) + width / 2
    lo[axis], hi[axis] = low[axis], high[axis]
    return lo.tolist(), hi.tolist()


def power_lines_scene() -> Scene:
    """The ground, the poles with their crossarms, the wires and the house fronts (see the
    module docstring)."""
    half = LINE_LENGTH / 2
    boxes = [([-half, -20.0, -0.5], [half, 20.0, 0.0])]  # ground
    boxes.append(([-half, HOUSE_FRONT_Y - 2.0, 0.0], [half, HOUSE_FRONT_Y, 6.0]))
    for x in np.arange(-half + POLE_SPACING / 2, half, POLE_SPACING):
        boxes.append(([x - 0.1, LINE_Y - 0.1, 0.0], [x + 0.1, LINE_Y + 0.1, POLE_HEIGHT]))
        boxes.append(([x - 0.05, LINE_Y - 0.9, 7.95], [x + 0.05, LINE_Y + 0.9, 8.1]))
    for dy, z in CONDUCTORS:
        boxes.append(_wire([-half, LINE_Y + dy, z], [half, LINE_Y + dy, z], CONDUCTOR_WIDTH, 0))
    boxes.append(_wire([-half, LINE_Y, CABLE_HEIGHT], [half, LINE_Y, CABLE_HEIGHT], CABLE_WIDTH, 0))
    crossing = ([CROSSING_X, HOUSE_FRONT_Y, CROSSING_HEIGHT], [CROSSING_X, LINE_Y, CROSSING_HEIGHT])
    boxes.append(_wire(*crossing, CONDUCTOR_WIDTH, 1))
    return scene_of(boxes, np.zeros((0, 3)), 0.0)


def power_lines(
    seed: int = 0,
    rings: int = 32,
    azimuths: int = 1024,
    noise_std: float = 0.02,
    max_range: float = 40.0,
) -> SimulatedDataset:
    """Five scans of a 32-ring LiDAR (rings x azimuths rays; elevations -22.5 to +22.5
    degrees, 1.8 m up, `max_range` metres) 10 m apart down the road under the line: for maps
    of 0.1 m."""
    directions = lidar_directions(rings, azimuths, 22.5)
    stops = (-20.0, -10.0, 0.0, 10.0, 20.0)
    return lidar_drive(
        "power_lines", power_lines_scene(), directions, stops, 0.0, max_range, noise_std, seed
    )
