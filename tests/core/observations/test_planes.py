"""Planes of a batch's hits: the normals found by cells, the wider cell for hits on lines, the
least spread of cells planar or not, and the compiled fit against its NumPy twin."""

import numpy as np
import pytest
from plane_points import assert_same_normals, planar_patches

from ehm.core.observations.planes import (
    cell_planes,
    cell_planes_reference,
    hit_planes,
    in_cells_of,
    in_cells_of_reference,
)


def test_hits_on_a_plane_have_its_normal_and_scattered_ones_none(rng):
    floor = np.column_stack([rng.uniform(0.01, 0.19, (20, 2)), np.full(20, 0.05)])
    scattered = rng.uniform(1.01, 1.19, (20, 3))
    normals = hit_planes(np.vstack([floor, scattered]), 0.2).normals
    np.testing.assert_allclose(np.abs(normals[:20]), np.tile([0.0, 0.0, 1.0], (20, 1)), atol=1e-9)
    assert np.isnan(normals[20:]).all()


def test_hits_on_rings_far_apart_find_their_plane_in_a_wider_cell(rng):
    """A wall (x = 1 m) hit along two LiDAR rings 9 cm apart: each 10 cm cell holds one ring,
    a line, and the 20 cm cell around both finds the wall's plane. A wall hit densely with
    1.5 cm of range noise is no plane in its 10 cm cells (least spread 0.27 of the next), and
    is not given the plane its 20 cm cell would find (0.07), but its least spread reads the
    noise, along the wall's normal."""
    y = np.arange(0.005, 0.2, 0.01)
    rings = np.column_stack([np.ones(40), np.tile(y, 2), np.repeat([0.02, 0.11], 20)])
    noisy = np.column_stack(
        [
            1.05 + np.clip(rng.normal(0.0, 0.015, 800), -0.045, 0.045),
            rng.uniform(0.0, 0.2, (800, 2)) + np.array([0.0, 0.2]),
        ]
    )
    planes = hit_planes(np.vstack([rings, noisy]), 0.1)
    normals = planes.normals
    np.testing.assert_allclose(np.abs(normals[:40]), np.tile([1.0, 0.0, 0.0], (40, 1)), atol=1e-9)
    assert np.isnan(normals[40:]).all()
    assert np.isnan(planes.spreads[:40]).all()  # lines: no least spread of their own
    assert np.all(np.abs(planes.spreads[40:] - 0.015) < 0.002)  # the noise's std
    assert np.all(np.abs(planes.axes[40:, 0]) > 0.99)
    wide = hit_planes(noisy, 0.2).normals
    np.testing.assert_allclose(np.abs(wide[:, 0]), 1.0, atol=0.01)


@pytest.mark.parametrize("dim", [2, 3])
def test_cell_planes_agree_with_their_numpy_twin(rng, dim):
    # Patches of planes (lines in 2D) with a little noise, lines, and scattered hits.
    line = np.outer(np.linspace(0.0, 0.1, 12), np.ones(dim)) + 3.0
    points = np.concatenate(
        [planar_patches(rng, dim, 80, 30, 0.05, 0.002), line, rng.uniform(-2.0, 2.0, (400, dim))]
    )
    compiled = cell_planes(points, 0.2)
    reference = cell_planes_reference(points, 0.2)
    np.testing.assert_array_equal(compiled.sparse, reference.sparse)
    planar = assert_same_normals(compiled.normals, reference.normals)
    assert planar.sum() > 100 and compiled.sparse.sum() > 300
    np.testing.assert_allclose(compiled.spreads, reference.spreads, rtol=1e-6, atol=1e-12)
    measured = ~compiled.sparse
    assert measured.sum() > planar.sum()  # planar cells and others
    # Axes of least spread agree up to sign where that spread stands apart from the next.
    dot = np.abs(np.einsum("nd,nd->n", compiled.axes[planar], reference.axes[planar]))
    np.testing.assert_allclose(dot, 1.0, atol=1e-6)


def test_wider_cells_give_sparse_hits_the_planes_of_the_whole_batch(rng):
    """hit_planes decomposes the wider cells of sparse hits from those cells' hits alone:
    their normals are those the wider cells of every hit give."""
    line = np.outer(np.linspace(0.0, 0.3, 40), [1.0, 0.0, 0.0]) + np.array([0.01, 2.02, 0.03])
    points = np.concatenate(
        [planar_patches(rng, 3, 60, 40, 0.05, 0.002), line, rng.uniform(-1.0, 1.0, (300, 3))]
    )
    planes = hit_planes(points, 0.1)
    narrow = cell_planes(points, 0.1)
    expected = narrow.normals.copy()
    expected[narrow.sparse] = cell_planes(points, 0.2).normals[narrow.sparse]
    assert narrow.sparse.sum() > 200 and np.isfinite(expected[narrow.sparse]).sum() > 10
    np.testing.assert_array_equal(planes.normals, expected)
    np.testing.assert_array_equal(planes.spreads, narrow.spreads)


def test_cells_of_rows_agree_with_their_numpy_twin(rng):
    keys = rng.integers(0, 500, 5000)
    rows = rng.choice(len(keys), 40, replace=False)
    inside = in_cells_of(keys, rows)
    np.testing.assert_array_equal(inside, in_cells_of_reference(keys, rows))
    assert 40 <= inside.sum() < 1000
