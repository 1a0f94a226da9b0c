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


@pytest.mark.parametrize(
    ("setting", "value", "message"),
    [
        ("planar_ratio", 1.0, "planar_ratio must be below 1"),
        ("planar_ratio", 0.0, "planar_ratio must be a positive number"),
        ("coplanar_angle", 90.0, "coplanar_angle must be below 90 degrees"),
        ("coplanar_distance", -1.0, "coplanar_distance must be a positive number"),
        ("anisotropic_candidates", 0, "anisotropic_candidates must be an integer >= 1"),
        ("anchor_layers", 0, "anchor_layers must be an integer >= 1"),
        ("anchor_radius_factor", 1.0, "anchor_radius_factor must be above 1"),
        ("train_search", "cluster", "train_search must be 'group' or 'point'"),
        ("memory_per_cell", -1, "memory_per_cell must be an integer >= 0"),
        ("memory_per_cell", 2.5, "memory_per_cell must be an integer >= 0"),
        ("replay_ratio", -0.5, "replay_ratio must be >= 0"),
        ("replay_ratio", float("nan"), "replay_ratio must be >= 0"),
    ],
)
def test_kernel_selection_search_and_hierarchy_settings_are_validated(setting, value, message):
    with pytest.raises(ValueError, match=message):
        MapConfig(**{setting: value})
