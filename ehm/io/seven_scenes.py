"""RGB-D frames in the layout of Microsoft's 7-Scenes, also used by tsdf-fusion and 3DMatch: a
folder of `frame-NNNNNN.depth.png` (16-bit, millimetres; 0 and 65535 are no reading) and
`frame-NNNNNN.pose.txt` (the 4x4 camera-to-world matrix, optical frame), with the camera in a
`camera-intrinsics.txt` (its 3x3 matrix) in the folder or the one above where present, else
7-Scenes' own Kinect (fx = fy = 585, cx 320, cy 240)."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike
from pathlib import Path

from ehm.errors import FileReadError, InputError, assumed
from ehm.io.depth import DepthCamera, DepthFrame
from ehm.io.poses import matrix_pose, read_matrix

SEVEN_SCENES_CAMERA = DepthCamera(585.0, 585.0, 320.0, 240.0, 1000.0, no_reading=(0, 65535))
DEPTH_SUFFIX, POSE_SUFFIX = ".depth.png", ".pose.txt"
INTRINSICS_FILE = "camera-intrinsics.txt"


def is_seven_scenes(folder: Path) -> bool:
    """Whether `folder` holds frames in the 7-Scenes layout."""
    return next(folder.glob(f"frame-*{DEPTH_SUFFIX}"), None) is not None


def seven_scenes_frames(
    folder: str | PathLike[str],
    intrinsics: Sequence[float] | None = None,
    depth_scale: float | None = None,
) -> tuple[DepthCamera, list[DepthFrame]]:
    """The camera and the posed depth frames of a 7-Scenes folder, in frame order; no image is
    read. `intrinsics` (fx, fy, cx, cy, pixels) and `depth_scale` (raw units a metre)
    replace the folder's own. FileReadError naming a frame without its pose file or a file
    that is not a matrix."""
    folder = Path(folder)
    camera = _camera(folder, intrinsics, depth_scale)
    frames = []
    for image in sorted(folder.glob(f"frame-*{DEPTH_SUFFIX}")):
        pose_path = image.with_name(image.name[: -len(DEPTH_SUFFIX)] + POSE_SUFFIX)
        if not pose_path.is_file():
            raise FileReadError(image, f"no pose: {pose_path.name} is missing")
        try:
            T_world_camera = matrix_pose(read_matrix(pose_path, (4, 4)).ravel())
        except InputError as error:
            raise FileReadError(pose_path, str(error)) from None
        frames.append(DepthFrame(image, T_world_camera, None))
    return camera, frames


def _camera(
    folder: Path, intrinsics: Sequence[float] | None, depth_scale: float | None
) -> DepthCamera:
    found = next(
        (p for p in (folder / INTRINSICS_FILE, folder.parent / INTRINSICS_FILE) if p.is_file()),
        None,
    )
    camera = SEVEN_SCENES_CAMERA
    if found is not None:
        K = read_matrix(found, (3, 3))
        try:
            camera = SEVEN_SCENES_CAMERA.with_options((K[0, 0], K[1, 1], K[0, 2], K[1, 2]), None)
        except InputError as error:
            raise FileReadError(found, str(error)) from None
    camera = camera.with_options(intrinsics, depth_scale)
    if found is None and intrinsics is None:
        assumed(
            f"{folder.name}: no {INTRINSICS_FILE}, so 7-Scenes' Kinect is assumed "
            f"({camera.describe()}); --intrinsics FX,FY,CX,CY says otherwise"
        )
    return camera
