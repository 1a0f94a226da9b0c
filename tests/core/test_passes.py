"""Rays passing through old occupied evidence: the compiled walk over the memory's regions
against its NumPy twin, and the cases that decide what a pass is."""

import numpy as np
import pytest

from ehm.config import MapConfig
from ehm.core.observations import passes as passes_module
from ehm.core.observations.evidence import FREE_AT_SURFACE, OCCUPIED, sample_flags
from ehm.core.observations.memory import EvidenceMemory
from ehm.core.observations.passes import occupied_passes, occupied_passes_reference
from ehm.core.observations.samples import ScanRays, TrainingSamples


def memory_of(points: np.ndarray, kinds: np.ndarray) -> EvidenceMemory:
    """A memory of fine cells of 5 cm (regions of 20 cm) holding one entry per point."""
    memory = EvidenceMemory(points.shape[1], True, (0.05, 0.3))
    occupied, at_surface = sample_flags(kinds)
    samples = TrainingSamples(points, occupied, at_surface)
    memory.insert(memory.visit(samples), np.ones(len(points), dtype=bool))
    return memory


def rays_of(origins: np.ndarray, ends: np.ndarray, hits: np.ndarray, margin: float) -> ScanRays:
    offsets = ends - origins
    lengths = np.linalg.norm(offsets, axis=1)
    free_end = np.where(hits, lengths - margin, lengths)
    spacing = np.full(len(lengths), 0.5)
    return ScanRays(
        origins,
        offsets / lengths[:, None],
        lengths,
        hits,
        np.zeros(len(lengths)),
        free_end,
        spacing,
    )


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("parallel", [False, True])
def test_passes_agree_with_their_numpy_twin(rng, monkeypatch, dim, parallel):
    if parallel:
        monkeypatch.setattr(passes_module, "PARALLEL_MIN_RAYS", 10)
    points = rng.uniform(-2.0, 2.0, (600, dim))
    kinds = rng.choice([OCCUPIED, FREE_AT_SURFACE], 600, p=[0.8, 0.2])
    memory = memory_of(points, kinds)
    origins = rng.uniform(-3.0, 3.0, (300, dim))
    ends = rng.uniform(-3.0, 3.0, (300, dim))
    rays = rays_of(origins, ends, rng.random(300) < 0.7, 0.05)
    entries, counts = occupied_passes(memory, rays, 0.08, 0.1)
    want_entries, want_counts = occupied_passes_reference(memory, rays, 0.08, 0.1)
    assert len(want_entries) > 50
    np.testing.assert_array_equal(entries, want_entries)
    np.testing.assert_array_equal(counts, want_counts)


def test_a_pass_needs_the_ray_to_go_on_beyond_the_entry():
    """An entry at x = 1 m: rays that pass it and end well beyond pass it once each; a ray
    that ends within `depth` of it, one that passes too far to the side and one whose free
    part ends before it do not."""
    memory = memory_of(np.array([[1.0, 0.0, 0.0]]), np.array([OCCUPIED]))
    origin = np.zeros(3)
    ends = np.array(
        [
            [3.0, 0.0, 0.0],  # passes through, hits 2 m beyond
            [3.0, 0.02, 0.0],  # passes 1 cm to the side
            [2.0, 0.0, 0.0],  # hits 1 m beyond, no return: passes
            [1.1, 0.0, 0.0],  # hits 0.1 m beyond: within depth
            [3.0, 0.3, 0.0],  # passes 10 cm to the side
            [0.9, 0.0, 0.0],  # ends before it
        ]
    )
    hits = np.array([True, True, False, True, True, True])
    rays = rays_of(np.tile(origin, (6, 1)), ends, hits, 0.05)
    entries, counts = occupied_passes(memory, rays, 0.03, 0.15)
    np.testing.assert_array_equal(entries, [0])
    np.testing.assert_array_equal(counts, [3])


def test_free_evidence_is_never_passed():
    memory = memory_of(np.array([[1.0, 0.0]]), np.array([FREE_AT_SURFACE]))
    rays = rays_of(np.zeros((1, 2)), np.array([[3.0, 0.0]]), np.array([True]), 0.05)
    entries, counts = occupied_passes(memory, rays, 0.03, 0.15)
    assert len(entries) == 0 and len(counts) == 0


def test_an_empty_memory_has_nothing_to_pass():
    memory = EvidenceMemory.of_config(3, MapConfig())
    rays = rays_of(np.zeros((1, 3)), np.ones((1, 3)), np.array([True]), 0.05)
    assert len(occupied_passes(memory, rays, 0.03, 0.15)[0]) == 0
