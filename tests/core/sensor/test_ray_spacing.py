"""The spacing of a scan's rays, as an angle, against the sensors' own geometry."""

import numpy as np
import pytest

from ehm.core.sensor.ray_spacing import angular_spacing
from ehm.eval.datasets.simulated import lidar_directions


def test_a_spinning_lidar_spaces_its_rays_by_its_solid_angle_over_their_number():
    directions = lidar_directions(16, 1024, 15.0)  # rings 2 degrees apart, azimuths 0.35
    spacing = angular_spacing(directions, np.zeros(len(directions), dtype=np.int64))
    band = 2.0 * np.pi * 2.0 * np.sin(np.radians(15.0))  # steradians between -15 and +15
    assert spacing == pytest.approx(np.sqrt(band / len(directions)), rel=0.1)
    assert np.ptp(spacing) == 0.0


def test_a_depth_camera_and_a_planar_laser():
    # 640 x 480 pixels over 58 x 45 degrees: 0.09 degrees apart.
    u, v = np.meshgrid(np.linspace(-0.55, 0.55, 640), np.linspace(-0.41, 0.41, 480))
    camera = np.column_stack([np.ones(u.size), u.ravel(), v.ravel()])
    camera /= np.linalg.norm(camera, axis=1, keepdims=True)
    spacing = angular_spacing(camera, np.zeros(len(camera), dtype=np.int64))
    assert np.degrees(spacing[0]) == pytest.approx(0.09, rel=0.25)
    turns = np.radians(np.arange(-90.0, 90.0, 1.0))  # 180 beams a degree apart
    laser = np.column_stack([np.cos(turns), np.sin(turns)])
    spacing = angular_spacing(laser, np.zeros(180, dtype=np.int64))
    assert np.degrees(spacing[0]) == pytest.approx(1.0, rel=0.05)


def test_each_scan_of_a_batch_has_its_own():
    sparse, dense = lidar_directions(16, 512, 15.0), lidar_directions(64, 1024, 15.0)
    directions = np.vstack([dense, sparse])
    scan_of = np.repeat([7, 2], [len(dense), len(sparse)])
    spacing = angular_spacing(directions, scan_of)
    alone = angular_spacing(sparse, np.zeros(len(sparse), dtype=np.int64))
    np.testing.assert_allclose(spacing[scan_of == 2], alone[0])
    assert spacing[0] == pytest.approx(spacing[-1] / np.sqrt(8.0), rel=0.05)
    assert len(angular_spacing(np.zeros((0, 3)), np.zeros(0, dtype=np.int64))) == 0
