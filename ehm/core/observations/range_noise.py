"""How far a batch's range noise spreads its hits along their rays, read off the hits.

Hits of one surface lie spread about it by the sensor's range noise. Where the hits of a cell
of a cluster radius lie on a surface, they spread about it by sigma_n along its normal (their
least spread, ehm.core.observations.planes.cell_planes), which is the noise along the rays
times the cosine between ray and normal: sigma_n / cos measures the noise along the rays.
At corners, edges and clutter the least spread is the shape's, not the noise's, so a batch
takes the median over its hits (at most MOST_MEASURED of them) in each of RANGE_BANDS bands
of range (as many hits in each): a depth camera's noise grows with range and a LiDAR's stays
as it is, and exact ranges on planes read 0. A surface lying on a face of the cells has its
band cut in two and reads less: a wall with 1 cm of noise on a face reads about half of it, in
the middle of its cells 0.9-1.
"""

from __future__ import annotations

import numpy as np

# Bands of range, as many measured hits in each, whose median noise each hit's range reads
# between (linearly, the nearest band's beyond the first and last).
RANGE_BANDS = 8
# Least cosine between a ray and the normal its noise is measured along: at grazing angles a
# cell's spread says little of the noise along the rays.
NOISE_COS_FLOOR = 0.3
# Most measured hits the bands' medians are taken over, evenly spaced among them: a band's
# median of 2,048 hits has a standard error of about 3 % of the noise, and sorting every hit of
# a depth frame was most of the reading's cost.
MOST_MEASURED = RANGE_BANDS * 2048


def range_noise(
    ranges: np.ndarray, directions: np.ndarray, spreads: np.ndarray, axes: np.ndarray
) -> np.ndarray:
    """(n,) metres, the standard deviation of the range noise at each of n hits' range:
    ranges (n,) metres; directions (n, d) unit, their rays'; spreads (n,) metres and axes
    (n, d) unit, the least spread of the hits of each one's cell and its axis, NaN where the
    cell measures none. Zeros when fewer hits than RANGE_BANDS measure it."""
    measured = np.flatnonzero(np.isfinite(spreads))
    if len(measured) < RANGE_BANDS:
        return np.zeros(len(ranges))
    if len(measured) > MOST_MEASURED:
        measured = measured[np.linspace(0, len(measured) - 1, MOST_MEASURED).astype(np.int64)]
    cosine = np.abs(np.einsum("nd,nd->n", directions[measured], axes[measured]))
    noise = spreads[measured] / np.maximum(cosine, NOISE_COS_FLOOR)
    order = np.argsort(ranges[measured], kind="stable")
    bands = np.array_split(order, RANGE_BANDS)
    band_ranges = np.array([np.median(ranges[measured[band]]) for band in bands])
    band_noise = np.array([np.median(noise[band]) for band in bands])
    return np.interp(ranges, band_ranges, band_noise)
