"""Every method behind the Mapper interface."""

import numpy as np
import pytest

from ehm.eval.baselines import METHODS, make_mapper, method_names
from ehm.eval.metrics import score
from ehm.eval.runner import run_method

# A word each method's description must hold: its name or its reference.
DESCRIBED_BY = {
    "octomap": "OctoMap (Hornung et al. 2013), 0.05 m voxels",
    "hm-fourier": "Fourier",
    "hm-nystrom": "Nystr",
    "hm-grid": "grid",
    "lls-hm": "LLS-HM (Guizilini & Ramos 2016)",
    "gpom": "2,000",
    "ehm": "EHM, incremental",
    "ehm-alone": "own samples alone",
    "ehm-realtime": "real-time profile",
    "ehm-batch": "EHM, single batch",
}


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_beats_chance_on_the_virtual_room(method, small_room_split, request):
    if method == "octomap":
        request.getfixturevalue("octomap_bindings")
    split = small_room_split
    mapper = make_mapper(method, 0.05, seed=0)
    probability, _, _ = run_method(mapper, split.train, split.points)
    assert probability.shape == (len(split.points),)
    assert np.all((probability >= 0.0) & (probability <= 1.0))
    s = score(split.occupied, probability)
    chance = max(split.occupied.mean(), 1.0 - split.occupied.mean())
    assert s.accuracy > chance + 0.1, s
    assert s.auc > 0.8, s
    assert mapper.memory_bytes() > 0
    assert DESCRIBED_BY[method] in mapper.description


def test_every_method_is_described():
    assert set(DESCRIBED_BY) == set(METHODS)


def test_method_names_expand_hm_and_name_unknown_methods():
    assert method_names(["hm", "ehm", "hm-grid"]) == ["hm-fourier", "hm-nystrom", "hm-grid", "ehm"]
    with pytest.raises(ValueError, match="unknown method 'voxblox'"):
        method_names(["voxblox"])
    with pytest.raises(ValueError, match="one method"):
        make_mapper("hm", 0.05, 0)


def test_settings_reach_ehm_methods_over_their_own_and_no_other():
    mapper = make_mapper("ehm-alone", 0.2, 3, {"front_reach": 2.0, "neighbours": 6})
    config = mapper.map.config
    assert (config.front_reach, config.neighbours, config.seed) == (2.0, 6, 3)
    assert config.cluster_radius == pytest.approx(0.48)  # the resolution's defaults beneath
    assert config.keep_evidence is False and config.batch_rays == 0  # and the kind's
    with pytest.raises(ValueError, match="settings are MapConfig's, for EHM methods"):
        make_mapper("octomap", 0.05, 0, {"front_reach": 2.0})
