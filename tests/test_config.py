import pytest

from ehm import HilbertMap, MapConfig


def test_overrides_and_validation():
    config = MapConfig().replace(neighbours=4)
    assert config.neighbours == 4
    assert MapConfig.from_dict(config.to_dict()) == config
    assert HilbertMap(cluster_radius=0.2).config.cluster_radius == 0.2
    with pytest.raises(ValueError, match="unknown MapConfig setting"):
        HilbertMap(radius=0.2)
    with pytest.raises(ValueError, match="cluster_radius must be a positive number"):
        MapConfig(cluster_radius=0)
    with pytest.raises(ValueError, match="merge_rule must be 'pooled' or 'average'"):
        MapConfig(merge_rule="mean")
    with pytest.raises(ValueError, match="neighbours must be an integer >= 1"):
        MapConfig(neighbours=0)
