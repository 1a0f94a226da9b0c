"""The mapping methods the evaluation compares, each behind one small interface (Mapper).

    mapper = make_mapper("gpom", resolution=0.05, seed=0)
    mapper.build(train_scans)              # everything the map needs before it can answer
    p = mapper.occupancy(points)           # (n,) probability of occupied; 0.5 = unknown
    mapper.memory_bytes()

Methods: see METHODS. `hm` stands for its three feature variants.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from ehm.core.sensor.scan import Scan
from ehm.errors import InputError


class Mapper(Protocol):
    """A mapping method under evaluation."""

    description: str
    """One line: the method, its reference and the settings that matter (such as a
    subsample size)."""

    def build(self, scans: list[Scan]) -> None:
        """Learn the scans, all of them, in order."""

    def occupancy(self, points: np.ndarray) -> np.ndarray:
        """(n,) float64 probability that each point (n, d), metres, world frame, is occupied;
        exactly 0.5 where the method knows nothing."""

    def memory_bytes(self) -> int:
        """Bytes the built map keeps to answer queries."""


def _octomap(resolution: float, seed: int) -> Mapper:
    from ehm.eval.baselines.octree import OctoMapMapper

    return OctoMapMapper(resolution)


def _hm(feature: str) -> Callable[[float, int], Mapper]:
    def make(resolution: float, seed: int) -> Mapper:
        from ehm.eval.baselines.hilbert_maps import HilbertMapsMapper

        return HilbertMapsMapper(feature, seed)

    return make


def _localized(kind: str) -> Callable[[float, int], Mapper]:
    def make(resolution: float, seed: int) -> Mapper:
        from ehm.eval.baselines.localized import LocalizedMapper

        return LocalizedMapper(kind, seed, resolution)

    return make


def _gpom(resolution: float, seed: int) -> Mapper:
    from ehm.eval.baselines.gpom import GPOccupancyMapper

    return GPOccupancyMapper(seed=seed)


METHODS: dict[str, Callable[[float, int], Mapper]] = {
    "octomap": _octomap,
    "hm-fourier": _hm("fourier"),
    "hm-nystrom": _hm("nystrom"),
    "hm-grid": _hm("grid"),
    "lls-hm": _localized("lls-hm"),
    "gpom": _gpom,
    "ehm": _localized("ehm"),
    "ehm-alone": _localized("ehm-alone"),
    "ehm-realtime": _localized("ehm-realtime"),
    "ehm-batch": _localized("ehm-batch"),
}
"""Every method by name, as a factory (resolution in metres, seed) -> Mapper."""

GROUPS: dict[str, list[str]] = {"hm": ["hm-fourier", "hm-nystrom", "hm-grid"]}
"""Names that stand for several methods."""


def method_names(names: list[str]) -> list[str]:
    """Expand group names ('hm') and check every name; ValueError names the unknown ones."""
    expanded: list[str] = []
    for name in names:
        for method in GROUPS.get(name, [name]):
            if method not in METHODS:
                known = ", ".join([*METHODS, *GROUPS])
                raise InputError(f"unknown method {name!r}; known: {known}")
            if method not in expanded:
                expanded.append(method)
    return expanded


def make_mapper(
    name: str, resolution: float, seed: int, settings: dict[str, Any] | None = None
) -> Mapper:
    """A fresh, empty mapper of method `name` (see METHODS); `settings`, MapConfig overrides,
    for an EHM method (ehm, ehm-alone, ehm-realtime, ehm-batch, lls-hm) only."""
    methods = method_names([name])
    if len(methods) != 1:
        raise InputError(f"{name!r} stands for {', '.join(methods)}: give one method")
    if not settings:
        return METHODS[methods[0]](resolution, seed)
    from ehm.eval.baselines.localized import KINDS, LocalizedMapper

    if methods[0] not in KINDS:
        raise InputError(f"settings are MapConfig's, for EHM methods; {name!r} takes none")
    return LocalizedMapper(methods[0], seed, resolution, settings)
