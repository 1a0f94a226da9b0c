"""A tree of coordinate frames over time, as ROS's tf keeps it: transforms between frames,
each static or stamped, looked up between any two connected frames at any time the stamps
cover, interpolated (position linearly, rotation by slerp).

    frames = FrameTree()
    frames.add("map", "base_link", stamp_ns, T_map_base)      # T_parent_child
    frames.add_static("base_link", "velodyne", T_base_velodyne)
    T_map_velodyne = frames.lookup("map", "velodyne", stamp_ns)
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from ehm.core.sensor.geometry import quaternion_to_matrix
from ehm.errors import InputError


@dataclass
class _Edge:
    """Transforms T_parent_child: static (one, stamps empty) or stamped (sorted on lookup)."""

    stamps: list[int] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    static: np.ndarray | None = None
    _sorted: tuple[np.ndarray, np.ndarray] | None = None

    def at(self, stamp: int) -> np.ndarray | None:
        """(4, 4) T_parent_child at `stamp` (ns), or None outside the stamps' span."""
        if self.static is not None:
            return self.static
        if self._sorted is None:
            order = np.argsort(self.stamps, kind="stable")
            self._sorted = (np.asarray(self.stamps)[order], np.stack(self.poses)[order])
        stamps, poses = self._sorted
        if not stamps[0] <= stamp <= stamps[-1]:
            return None
        after = int(np.searchsorted(stamps, stamp, side="left"))
        if stamps[after] == stamp:
            return poses[after]
        share = (stamp - stamps[after - 1]) / (stamps[after] - stamps[after - 1])
        return interpolate_pose(poses[after - 1], poses[after], float(share))


class FrameTree:
    """Frames joined by transforms (see the module)."""

    def __init__(self) -> None:
        self._edges: dict[tuple[str, str], _Edge] = {}
        self._neighbours: dict[str, set[str]] = {}

    @property
    def frames(self) -> list[str]:
        return sorted(self._neighbours)

    def add(self, parent: str, child: str, stamp: int, T_parent_child: np.ndarray) -> None:
        """A transform from `child` to `parent` frame at `stamp`, nanoseconds."""
        edge = self._edge(parent, child)
        edge.stamps.append(int(stamp))
        edge.poses.append(np.asarray(T_parent_child, dtype=np.float64))
        edge._sorted = None

    def add_static(self, parent: str, child: str, T_parent_child: np.ndarray) -> None:
        """A transform from `child` to `parent` frame at all times."""
        self._edge(parent, child).static = np.asarray(T_parent_child, dtype=np.float64)

    def lookup(self, target: str, source: str, stamp: int) -> np.ndarray | None:
        """(4, 4) T_target_source at `stamp` (ns): points in `source` frame to `target` frame;
        None where a transform on the way has no stamps around `stamp`. InputError when the
        frames are not connected."""
        path = self._path(_name(target), _name(source))
        T = np.eye(4)
        for a, b in pairwise(path):
            if (a, b) in self._edges:
                step = self._edges[(a, b)].at(stamp)
            else:
                inverse = self._edges[(b, a)].at(stamp)
                step = None if inverse is None else invert_pose(inverse)
            if step is None:
                return None
            T = T @ step
        return T

    def _edge(self, parent: str, child: str) -> _Edge:
        parent, child = _name(parent), _name(child)
        if (child, parent) in self._edges:
            raise InputError(f"transforms given both from {parent} to {child} and back")
        self._neighbours.setdefault(parent, set()).add(child)
        self._neighbours.setdefault(child, set()).add(parent)
        return self._edges.setdefault((parent, child), _Edge())

    def _path(self, target: str, source: str) -> list[str]:
        """Frames from `target` to `source`, each joined to the next by a transform."""
        for frame in (target, source):
            if frame not in self._neighbours:
                known = ", ".join(self.frames) or "none"
                raise InputError(f"no transforms involve frame {frame!r} (frames: {known})")
        previous = {target: target}
        queue = deque([target])
        while queue:
            frame = queue.popleft()
            for neighbour in self._neighbours[frame]:
                if neighbour not in previous:
                    previous[neighbour] = frame
                    queue.append(neighbour)
        if source not in previous:
            raise InputError(f"no chain of transforms joins frame {target!r} to {source!r}")
        path = [source]
        while path[-1] != target:
            path.append(previous[path[-1]])
        return path[::-1]


def _name(frame: str) -> str:
    """A frame's name without the leading slash ROS 1 allowed ("/base_link" is "base_link")."""
    return frame.lstrip("/")


def invert_pose(T: np.ndarray) -> np.ndarray:
    """(4, 4) inverse of a rigid transform."""
    inverse = np.eye(4)
    inverse[:3, :3] = T[:3, :3].T
    inverse[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return inverse


def interpolate_pose(a: np.ndarray, b: np.ndarray, share: float) -> np.ndarray:
    """The rigid transform `share` (0 to 1) of the way from `a` to `b`: translation linear,
    rotation along the shortest arc (slerp)."""
    qa, qb = matrix_to_quaternion(a[:3, :3]), matrix_to_quaternion(b[:3, :3])
    if qa @ qb < 0:
        qb = -qb
    angle = np.arccos(np.clip(qa @ qb, -1.0, 1.0))
    if angle < 1e-9:
        q = qa
    else:
        q = (np.sin((1 - share) * angle) * qa + np.sin(share * angle) * qb) / np.sin(angle)
    pose = np.eye(4)
    pose[:3, :3] = quaternion_to_matrix(*q)
    pose[:3, 3] = (1 - share) * a[:3, 3] + share * b[:3, 3]
    return pose


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    w = np.sqrt(max(0.0, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2.0
    x = np.copysign(np.sqrt(max(0.0, 1.0 + R[0, 0] - R[1, 1] - R[2, 2])) / 2.0, R[2, 1] - R[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - R[0, 0] + R[1, 1] - R[2, 2])) / 2.0, R[0, 2] - R[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - R[0, 0] - R[1, 1] + R[2, 2])) / 2.0, R[1, 0] - R[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)
