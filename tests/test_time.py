"""Time stamps: scans carry them, maps keep them, and a map with forget_after lets what it has
not seen for that long fade back to unknown while it keeps what it sees."""

import copy

import numpy as np
import pytest

import ehm
from ehm.errors import InputError

# Walls at x = 2 (seen at time 0 only) and x = -2 (seen from time 1 on), from the origin.
EAST, WEST = np.array([[2.0, 0.0], [1.0, 0.0]]), np.array([[-2.0, 0.0], [-1.0, 0.0]])


def wall_scan(x: float, time: float) -> ehm.Scan:
    y = np.linspace(-1.5, 1.5, 181)
    return ehm.Scan(np.column_stack([np.full(181, x), y]), np.zeros(2), time=time)


def east_then_west(**overrides) -> ehm.HilbertMap:
    """A map that sees the east wall at time 0, then only the west one, once a second to 12 s."""
    hilbert_map = ehm.HilbertMap(**overrides).integrate_scan(wall_scan(2.0, 0.0)).flush()
    for time in range(1, 13):
        hilbert_map.integrate_scan(wall_scan(-2.0, float(time)))
    return hilbert_map.flush()


def test_what_goes_unseen_fades_to_unknown_and_what_is_seen_stays():
    kept, faded = east_then_west(), east_then_west(forget_after=2.0)
    assert kept.occupancy(EAST)[0] > 0.7
    # 20 quarters of forget_after past it: the east wall reads as the same map with every
    # weight at its prior does, occupancy and std.
    p, std = faded.occupancy(EAST[:1], return_std=True)
    prior = ehm.HilbertMap.from_state(copy.deepcopy(faded.state()))
    prior.clusters_.weights[:] = 0.0
    prior.clusters_.precision[:] = faded.config.prior_precision
    p_prior, std_prior = prior.occupancy(EAST[:1], return_std=True)
    assert p[0] == pytest.approx(0.5, abs=1e-4) and p_prior[0] == 0.5
    assert std[0] == pytest.approx(std_prior[0], rel=1e-3)
    assert std[0] > 1.3 * kept.occupancy(EAST[:1], return_std=True)[1][0]
    # The west wall, seen all along, reads as it does in the map that keeps everything.
    np.testing.assert_allclose(faded.occupancy(WEST), kept.occupancy(WEST), atol=0.02)
    assert faded.occupancy(WEST)[0] > 0.9
    assert faded.time_ == kept.time_ == 12.0


def test_time_stamps_change_nothing_for_a_map_that_does_not_fade(plan):
    stamped, plain = ehm.HilbertMap(), ehm.HilbertMap()
    for i, scan in enumerate(plan.scans[:4]):
        stamped.integrate(scan.points_world, scan.origin, scan.hit_mask, time=100.0 + i)
        plain.integrate_scan(scan)
    stamped.flush()
    plain.flush()
    np.testing.assert_array_equal(stamped.clusters_.weights, plain.clusters_.weights)
    assert stamped.time_ == 103.0 and plain.time_ is None
    assert np.isnan(stamped.clusters_.seen).all()


def test_a_map_that_fades_wants_every_scan_stamped(plan):
    scan = plan.scans[0]
    hilbert_map = ehm.HilbertMap(forget_after=60.0)
    with pytest.raises(InputError, match=r"has no time stamp.*forget_after"):
        hilbert_map.integrate_scan(scan)
    assert hilbert_map.n_scans_ == 0
    with pytest.raises(InputError, match="scan 1 has no time stamp"):
        hilbert_map.fit([wall_scan(2.0, 0.0), scan])
    with pytest.raises(InputError, match="finite number of seconds, got 'noon'"):
        ehm.Scan(scan.points_world, scan.origin, time="noon")
    assert wall_scan(2.0, 5.0).subset(np.arange(10)).time == 5.0


def test_times_are_saved_with_the_map_and_it_goes_on_fading_as_it_would(tmp_path):
    original = ehm.HilbertMap(forget_after=2.0, batch_rays=400)
    for time in range(4):
        original.integrate_scan(wall_scan(2.0 if time == 0 else -2.0, float(time)))
    assert original.n_waiting_scans == 1
    original.save(tmp_path / "m.ehm")
    loaded = ehm.load(tmp_path / "m.ehm")
    assert loaded.time_ == original.time_ and loaded.state().waiting[0].time == 3.0
    for time in range(4, 9):
        for hilbert_map in (original, loaded):
            hilbert_map.integrate_scan(wall_scan(-2.0, float(time)))
    original.flush()
    loaded.flush()
    for name, array in original.clusters_.arrays().items():
        np.testing.assert_array_equal(getattr(loaded.clusters_, name), array, err_msg=name)
    np.testing.assert_array_equal(loaded.model_.memory.seen, original.model_.memory.seen)
    assert original.last_update_["faded_clusters"] > 0
