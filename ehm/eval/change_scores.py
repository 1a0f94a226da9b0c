"""How a map follows a changing scene (ehm.eval.datasets.changing), measured in voxels of one
resolution on OctoMap's grid (voxel k spans [k, k + 1) times the resolution, read at its
centre):

- ghosts: voxels of a departed object's surface that rays have passed through since it left,
  still read occupied; counted by how many scans have passed through each (1 = the first),
  until it comes back, if it does;
- arrivals: voxels of an arrived object's surface that a scan hit, read occupied; counted by
  how many scans have seen each; alike for a departed object that came back (returns);
- trail: voxels a walker's surface stood in (a scan hit it there), that it has left and that
  rays have passed through since, read occupied;
- static: points near the surfaces that never move, against their exact occupancy.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.eval.datasets.changing import ChangingDataset, Mover
from ehm.eval.metrics import f1_score, precision_recall
from ehm.eval.protocol import observed_mask

# Points near static surfaces: uniform in balls of this radius around hits, metres; none
# within this distance of any place a mover ever was.
NEAR = 0.3


def voxel_keys(points: np.ndarray, resolution: float) -> np.ndarray:
    """(n, d) int64 voxel of each of (n, d) points, metres."""
    return np.floor(np.asarray(points) / resolution).astype(np.int64)


def voxel_centres(keys: np.ndarray, resolution: float) -> np.ndarray:
    """(n, d) float64 metres: the centres of voxels `keys` (n, d)."""
    return (keys + 0.5) * resolution


def _rows(keys: np.ndarray) -> np.ndarray:
    """(n,) void view of (n, d) int64 keys, for set operations on rows."""
    keys = np.ascontiguousarray(keys, dtype=np.int64)
    return keys.view(np.dtype((np.void, keys.dtype.itemsize * keys.shape[1]))).ravel()


def contains(keys: np.ndarray, among: np.ndarray) -> np.ndarray:
    """(n,) bool: which rows of keys (n, d) are rows of among (m, d)."""
    return np.isin(_rows(keys), _rows(among))


def shell_voxels(box: np.ndarray, resolution: float) -> np.ndarray:
    """(n, d) int64: the voxels whose centres lie inside `box` (2, d), metres, within one
    resolution of its surface."""
    low = np.floor(box[0] / resolution).astype(np.int64)
    high = np.floor(box[1] / resolution).astype(np.int64)
    axes = [np.arange(lo, hi + 1) for lo, hi in zip(low, high, strict=True)]
    keys = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(low))
    centres = voxel_centres(keys, resolution)
    depth = np.minimum(centres - box[0], box[1] - centres).min(axis=1)
    return keys[(depth >= 0.0) & (depth <= resolution)]


def passed_voxels(scan: Scan, box: np.ndarray, resolution: float) -> np.ndarray:
    """(m, d) int64 distinct voxels inside `box` (2, d), metres, that the free part of some
    ray of `scan` crosses: up to one resolution before a hit, or the whole of a ray without
    return (sampled every quarter resolution)."""
    offsets = scan.points_world - scan.origin
    lengths = np.linalg.norm(offsets, axis=1)
    directions = offsets / np.maximum(lengths, 1e-12)[:, None]
    free = np.where(scan.hit_mask, lengths - resolution, lengths)
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (box[0] - scan.origin) / directions
        t1 = (box[1] - scan.origin) / directions
    enter = np.nanmax(np.minimum(t0, t1), axis=1).clip(min=0.0)
    leave = np.minimum(np.nanmin(np.maximum(t0, t1), axis=1), free)
    crossing = np.flatnonzero(leave > enter)
    if len(crossing) == 0:
        return np.zeros((0, scan.dim), dtype=np.int64)
    steps = np.ceil((leave - enter)[crossing] / (0.25 * resolution)).astype(np.int64) + 1
    ray = np.repeat(crossing, steps)
    fraction = (np.arange(steps.sum()) - np.repeat(np.cumsum(steps) - steps, steps)) / np.repeat(
        steps - 1, steps
    ).clip(min=1)
    t = enter[ray] + fraction * (leave[ray] - enter[ray])
    points = scan.origin + directions[ray] * t[:, None]
    return np.unique(voxel_keys(points, resolution), axis=0)


def hit_voxels(scan: Scan, box: np.ndarray, resolution: float) -> np.ndarray:
    """(m, d) int64 distinct voxels of the hits of `scan` within one resolution of `box`
    (2, d), metres."""
    hits = scan.points_world[scan.hit_mask]
    near = np.all((hits >= box[0] - resolution) & (hits <= box[1] + resolution), axis=1)
    return np.unique(voxel_keys(hits[near], resolution), axis=0)


@dataclass
class Tally:
    """Voxels read occupied out of voxels read, by how many scans each has been through
    (1 = the first)."""

    occupied: dict[int, int] = field(default_factory=dict)
    read: dict[int, int] = field(default_factory=dict)

    def add(self, scans_since: np.ndarray, occupied: np.ndarray) -> None:
        for k in np.unique(scans_since):
            at = scans_since == k
            self.occupied[int(k)] = self.occupied.get(int(k), 0) + int(occupied[at].sum())
            self.read[int(k)] = self.read.get(int(k), 0) + int(at.sum())

    def share(self, k: int) -> float:
        """Share read occupied among voxels k scans through; NaN when none were read."""
        return self.occupied[k] / self.read[k] if self.read.get(k) else float("nan")


@dataclass(frozen=True)
class _Tracked:
    """Voxels (n, d) int64 and the scan from which on each counts (n,) int64, n_scans where
    never."""

    keys: np.ndarray
    since: np.ndarray


class ChangeProbe:
    """The voxels and points that measure how a map follows `dataset` (see the module's
    docstring), found from its scans and exact scenes at `resolution` metres; `measure` reads
    them from a map after each scan."""

    def __init__(
        self, dataset: ChangingDataset, resolution: float, rng: np.random.Generator
    ) -> None:
        self.dataset, self.resolution = dataset, resolution
        n = len(dataset.scans)
        self.ghosts = _departures(dataset.mover("departs"), dataset.scans, resolution)
        self.arrivals = _arrivals(dataset.mover("arrives"), dataset.scans, resolution)
        nothing = np.zeros((0, dataset.scans[0].dim), dtype=np.int64)
        self.returns = _Tracked(nothing, np.zeros(0, dtype=np.int64))
        self.ghosts_until = n
        if dataset.has("returns"):
            self.returns = _arrivals(dataset.mover("returns"), dataset.scans, resolution)
            self.ghosts_until = _first_present(dataset.mover("returns"), n)
        self.trail = _trail(dataset.mover("walks"), dataset.scans, resolution)
        self.ghost_tally, self.arrival_tally, self.return_tally = Tally(), Tally(), Tally()
        self.near = _static_near_points(dataset, rng)
        self.near_occupied = dataset.static.occupied(self.near)

    def measure(self, scan: int, occupancy: Callable[[np.ndarray], np.ndarray]) -> dict:
        """After the map learned scans 0..scan: ghost and arrival tallies grow; returns the
        share of the trail read occupied and near-surface precision, recall and F1 on the
        static parts."""
        res = self.resolution
        for tracked, tally, until in (
            (self.ghosts, self.ghost_tally, self.ghosts_until),
            (self.arrivals, self.arrival_tally, len(self.dataset.scans)),
            (self.returns, self.return_tally, len(self.dataset.scans)),
        ):
            counted = (tracked.since <= scan) & (scan < until)
            if counted.any():
                occupied = occupancy(voxel_centres(tracked.keys[counted], res)) > 0.5
                tally.add(scan - tracked.since[counted] + 1, occupied)
        left = self.trail.since <= scan
        trail = float("nan")
        if left.any():
            trail = float(np.mean(occupancy(voxel_centres(self.trail.keys[left], res)) > 0.5))
        predicted = occupancy(self.near) > 0.5
        precision, recall = precision_recall(self.near_occupied, predicted)
        return {
            "trail": trail,
            "near precision": precision,
            "near recall": recall,
            "near F1": f1_score(self.near_occupied, predicted),
        }


def _departures(mover: Mover, scans: list[Scan], resolution: float) -> _Tracked:
    """The surface voxels of a departing mover seen while it was there, each from the first
    scan after it left that passes through it."""
    present = [i for i in range(len(scans)) if mover.present(i)]
    box = mover.boxes[present[-1]]
    seen = np.concatenate([hit_voxels(scans[i], box, resolution) for i in present])
    keys = shell_voxels(box, resolution)
    keys = keys[contains(keys, seen)]
    since = np.full(len(keys), len(scans))
    for i in range(present[-1] + 1, len(scans)):
        passed = contains(keys, passed_voxels(scans[i], box, resolution))
        since = np.where(passed & (since == len(scans)), i, since)
    return _Tracked(keys, since)


def _first_present(mover: Mover, n_scans: int) -> int:
    """The first scan `mover` is present in (n_scans: none)."""
    return next((i for i in range(n_scans) if mover.present(i)), n_scans)


def _arrivals(mover: Mover, scans: list[Scan], resolution: float) -> _Tracked:
    """The surface voxels of an arriving mover, each from the first scan that hits it."""
    present = [i for i in range(len(scans)) if mover.present(i)]
    box = mover.boxes[present[0]]
    keys = shell_voxels(box, resolution)
    since = np.full(len(keys), len(scans))
    for i in present:
        hit = contains(keys, hit_voxels(scans[i], box, resolution))
        since = np.where(hit & (since == len(scans)), i, since)
    return _Tracked(keys, since)


def _trail(mover: Mover, scans: list[Scan], resolution: float) -> _Tracked:
    """The voxels where a scan hit a walking mover, each from the first later scan that
    passes through it while the mover is elsewhere (none that any solid fills at the end)."""
    n = len(scans)
    stood = [
        (i, hit_voxels(scans[i], mover.boxes[i], resolution)) for i in range(n) if mover.present(i)
    ]
    keys = np.unique(np.concatenate([k for _, k in stood]), axis=0)
    first_stood = np.full(len(keys), n)
    for i, hit in reversed(stood):
        first_stood = np.where(contains(keys, hit), i, first_stood)
    since = np.full(len(keys), n)
    room = np.array([keys.min(axis=0), keys.max(axis=0) + 1]) * resolution
    for i in range(n):
        inside = np.zeros(len(keys), dtype=bool)
        if mover.present(i):
            centres = voxel_centres(keys, resolution)
            inside = np.all((centres >= mover.boxes[i][0]) & (centres <= mover.boxes[i][1]), 1)
        passed = contains(keys, passed_voxels(scans[i], room, resolution)) & ~inside
        since = np.where(passed & (i > first_stood) & (since == n), i, since)
    return _Tracked(keys, since)


def _static_near_points(dataset: ChangingDataset, rng: np.random.Generator) -> np.ndarray:
    """(m, d) points uniform in balls of NEAR metres around hits of every scan, observed by
    them, none within NEAR of a place any mover was in."""
    scans = dataset.scans
    hits = np.concatenate([s.points_world[s.hit_mask] for s in scans])
    d = hits.shape[1]
    n = 50_000
    directions = rng.normal(size=(n, d))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    points = (
        hits[rng.integers(0, len(hits), n)]
        + directions * (NEAR * rng.random(n) ** (1.0 / d))[:, None]
    )
    clear = np.ones(len(points), dtype=bool)
    for mover in dataset.movers:
        for box in mover.boxes[np.all(np.isfinite(mover.boxes), axis=(1, 2))]:
            clear &= ~np.all((points >= box[0] - NEAR) & (points <= box[1] + NEAR), axis=1)
    points = points[clear]
    return points[observed_mask(scans, points, 0.05)]
