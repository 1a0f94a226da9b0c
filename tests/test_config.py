import pytest

from ehm import HilbertMap, MapConfig, SettingsError
from ehm.config import (
    DEFAULT_RESOLUTION,
    LENGTH_SETTINGS,
    REALTIME,
    REALTIME_CLUSTER_SCALE,
    SECTIONS,
)


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
        ("occupied_length_scale", 0.0, "occupied_length_scale must be a positive number"),
        ("anisotropic_candidates", 0, "anisotropic_candidates must be an integer >= 1"),
        ("anchor_layers", 0, "anchor_layers must be an integer >= 1"),
        ("anchor_radius_factor", 1.0, "anchor_radius_factor must be above 1"),
        ("train_search", "cluster", "train_search must be 'group' or 'point'"),
        ("features", "all", "features must be 'support' or 'nearest', got 'all'"),
        ("keep_evidence", 1, "keep_evidence must be True or False, got 1"),
        ("batch_rays", -1, "batch_rays must be an integer >= 0"),
        ("l2", float("nan"), "l2 must be a finite number, got nan"),
        ("cluster_radius", float("inf"), "cluster_radius must be a finite number, got inf"),
        ("learning_rate", "0.3", "learning_rate must be a finite number, got '0.3'"),
        ("min_std", 1e-300, "min_std must be at least 1e-06 m"),
        ("planar_kernel", "maybe", "planar_kernel must be True or False, got 'maybe'"),
        ("balance_classes", 1, "balance_classes must be True or False, got 1"),
        ("batch_rays", 1e4, "batch_rays must be an integer >= 0"),
        ("replay_ratio", -0.5, "replay_ratio must be >= 0"),
        ("replay_ratio", float("nan"), "replay_ratio must be a finite number, got nan"),
        ("replay_cap", 0.0, "replay_cap must be None or a positive number, got 0.0"),
        ("replay_cap", float("inf"), "replay_cap must be a finite number, got inf"),
        ("replay_cap", -1, "replay_cap must be None or a positive number, got -1"),
        ("pass_retraction", 1.5, "pass_retraction must be between 0 and 1, got 1.5"),
        ("pass_retraction", -0.1, "pass_retraction must be between 0 and 1, got -0.1"),
        ("min_range", -0.1, "min_range must be >= 0"),
        ("max_range", -1.0, r"max_range must be 0 \(no limit\) or above min_range"),
        ("max_range", float("inf"), "max_range must be a finite number"),
        ("max_free_samples", 0, "max_free_samples must be an integer >= 1"),
        ("free_thinning", 0, "free_thinning must be an integer >= 1"),
        ("surface_pooling", 0, "surface_pooling must be an integer >= 1, got 0"),
        ("surface_pooling", 1.5, "surface_pooling must be an integer >= 1, got 1.5"),
        ("front_reach", 0.5, "front_reach must be >= 1, got 0.5"),
        ("front_reach", float("nan"), "front_reach must be a finite number, got nan"),
        ("front_stretch", 1, "front_stretch must be True or False, got 1"),
    ],
)
def test_settings_are_validated(setting, value, message):
    with pytest.raises(SettingsError, match=message):
        MapConfig(**{setting: value})


def test_max_range_lies_beyond_min_range():
    assert MapConfig(min_range=0.5, max_range=30.0).max_range == 30.0
    with pytest.raises(SettingsError, match=r"above min_range \(2.0 m\), got 1.0"):
        MapConfig(min_range=2.0, max_range=1.0)


def test_settings_for_another_resolution_scale_every_length():
    default = MapConfig()
    assert MapConfig.for_resolution(DEFAULT_RESOLUTION) == default
    coarse = MapConfig.for_resolution(0.2, neighbours=6, cluster_radius=0.3)
    for name in LENGTH_SETTINGS:
        if getattr(default, name) is None:  # off stays off
            assert getattr(coarse, name) is None, name
            continue
        expected = 0.3 if name == "cluster_radius" else 4.0 * getattr(default, name)
        assert getattr(coarse, name) == pytest.approx(expected), name
    assert coarse.neighbours == 6 and coarse.length_scale == default.length_scale
    for bad in (0.0, -0.1, float("inf"), float("nan"), "0.2"):
        with pytest.raises(ValueError, match="map resolution must be a positive number"):
            MapConfig.for_resolution(bad)


def test_a_configuration_knows_the_resolution_it_was_made_for():
    assert MapConfig().resolution == DEFAULT_RESOLUTION
    assert MapConfig.for_resolution(0.2).resolution == pytest.approx(0.2)
    assert MapConfig.for_resolution(0.1, max_range=30.0).resolution == pytest.approx(0.1)


def test_the_real_time_profile_learns_less_and_keeps_its_resolution():
    default = MapConfig.for_resolution(0.1)
    realtime = MapConfig.for_resolution(0.1, "realtime", max_range=40.0)
    assert realtime.resolution == 0.1 and realtime.voxel_size == 0.1
    assert realtime.cluster_radius == pytest.approx(REALTIME_CLUSTER_SCALE * default.cluster_radius)
    assert {name: getattr(realtime, name) for name in REALTIME} == REALTIME
    assert realtime.max_range == 40.0 and realtime.neighbours == default.neighbours
    assert MapConfig.for_resolution(0.1, "default") == default
    # A settings file keeps the profile's settings, and rescales its resolution with them.
    assert MapConfig.from_toml(realtime.to_toml()) == realtime
    rescaled = MapConfig.from_toml(realtime.to_toml(), resolution=0.2)
    assert rescaled == MapConfig.for_resolution(0.2, "realtime", max_range=40.0)
    assert MapConfig.of(resolution=0.1, profile="realtime", max_range=40.0) == realtime
    with pytest.raises(SettingsError, match="profile must be 'default' or 'realtime', got 'fast'"):
        MapConfig.for_resolution(0.1, "fast")


def test_settings_files_round_trip_in_sections():
    config = MapConfig.for_resolution(0.2, replay_cap=None, learn_box=(0, 0, 0, 4, 4, 2))
    text = config.to_toml()
    assert "[clustering]\ncluster_radius = 0.48\n" in text and 'replay_cap = "none"' in text
    assert MapConfig.from_toml(text) == config
    assert set(config.section("memory")) == {
        "keep_evidence", "replay_ratio", "replay_cap", "pass_retraction", "forget_after",
    }  # fmt: skip
    assert sum(len(config.section(name)) for name in SECTIONS) == len(config.to_dict())


def test_a_settings_file_may_be_partial_flat_or_at_another_resolution():
    partial = MapConfig.from_toml(
        "resolution = 0.1\n[kernels]\nneighbours = 6\nfeatures = 'support'\n"
    )
    assert partial == MapConfig.for_resolution(0.1, neighbours=6, features="support")
    assert MapConfig.from_toml("neighbours = 6") == MapConfig(neighbours=6)
    # Another resolution scales the file's lengths, as it scales the defaults.
    rescaled = MapConfig.from_toml(MapConfig().to_toml(), resolution=0.2)
    assert rescaled == MapConfig.for_resolution(0.2)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[kernels]\ncluster_radius = 0.2\n",
            r"\[kernels\] has no setting 'cluster_radius' \(it is in \[clustering\]\)",
        ),
        ("[kernels]\nradius = 0.2\n", r"\[kernels\] has no setting 'radius'$"),
        ("neighbours = 0\n", "a.toml: MapConfig.neighbours must be an integer >= 1, got 0"),
        ("resolution = -1\n", "a.toml: resolution must be a positive number of metres"),
        ("neighbours = \n", "a.toml: not TOML"),
        ("speed = 3\n", "a.toml: unknown MapConfig setting"),
    ],
)
def test_settings_files_are_refused_by_name(text, message):
    with pytest.raises(SettingsError, match=message):
        MapConfig.from_toml(text, "a.toml")
