import numpy as np
import pytest

from ehm.baselines import METHODS, make_mapper, method_names
from ehm.baselines.gpom import balanced_subsample, plsc_fit
from ehm.baselines.hilbert_maps import (
    FourierFeatures,
    GridFeatures,
    HilbertMapsSettings,
    NystromFeatures,
    SparseRows,
    logistic_sgd,
    rbf_kernel,
)
from ehm.comparison import run_method
from ehm.datasets import virtual_room
from ehm.evaluation import held_out_rays, score
from ehm.kernels import sparse_kernel_reference


@pytest.fixture(scope="module")
def small_room_split():
    """A coarse scan of the virtual room (about 12,000 rays), 60 % of its rays to train."""
    data = virtual_room(seed=0, rings=24, azimuths=500)
    return held_out_rays(data.scans, 0.6, 0.05, seed=0)


def _has_octomap() -> bool:
    try:
        import octomap  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_beats_chance_on_the_virtual_room(method, small_room_split):
    if method == "octomap" and not _has_octomap():
        pytest.skip("OctoMap bindings not installed (pip install 'ehm[octomap]')")
    split = small_room_split
    mapper = make_mapper(method, 0.05, seed=0)
    probability, build_s, query_s = run_method(mapper, split.train, split.points)
    s = score(split.occupied, probability)
    chance = max(split.occupied.mean(), 1.0 - split.occupied.mean())
    assert s.accuracy > chance + 0.1, s
    assert s.auc > 0.8, s
    assert mapper.memory_bytes() > 0
    assert build_s > 0 and query_s > 0
    assert mapper.description


def test_octomap_reads_unknown_space_as_one_half(small_room_split):
    if not _has_octomap():
        pytest.skip("OctoMap bindings not installed (pip install 'ehm[octomap]')")
    mapper = make_mapper("octomap", 0.05, seed=0)
    mapper.build(small_room_split.train)
    far = np.array([[50.0, 50.0, 50.0], [-40.0, 0.0, 1.0]])
    np.testing.assert_array_equal(mapper.occupancy(far), [0.5, 0.5])


def test_octomap_maps_2d_scans_in_a_plane():
    if not _has_octomap():
        pytest.skip("OctoMap bindings not installed (pip install 'ehm[octomap]')")
    from ehm.scan import Scan

    angles = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    ring = 3.0 * np.column_stack([np.cos(angles), np.sin(angles)])
    mapper = make_mapper("octomap", 0.05, seed=0)
    mapper.build([Scan(ring, np.zeros(2))])
    p = mapper.occupancy(np.array([[3.0, 0.0], [1.5, 0.0], [9.0, 0.0]]))
    assert p[0] > 0.5 and p[1] < 0.5 and p[2] == 0.5


def test_method_names_expand_hm_and_name_unknown_methods():
    assert method_names(["hm", "ehm", "hm-grid"]) == ["hm-fourier", "hm-nystrom", "hm-grid", "ehm"]
    with pytest.raises(ValueError, match="unknown method 'voxblox'"):
        method_names(["voxblox"])
    with pytest.raises(ValueError, match="one method"):
        make_mapper("hm", 0.05, 0)


def test_fourier_features_approximate_the_rbf_kernel(rng):
    features = FourierFeatures(3, 20_000, 0.5, rng)
    points = rng.uniform(-0.5, 0.5, (30, 3))
    phi = features(points)
    np.testing.assert_allclose(phi @ phi.T, rbf_kernel(points, points, 0.5), atol=0.03)


def test_nystrom_features_reproduce_the_kernel_on_inducing_points(rng):
    samples = rng.uniform(-1, 1, (400, 3))
    features = NystromFeatures(samples, 50, 0.5, rng)
    phi = features(features.inducing)
    expected = rbf_kernel(features.inducing, features.inducing, 0.5)
    np.testing.assert_allclose(phi @ phi.T, expected, atol=1e-6)


@pytest.mark.parametrize("dim", [2, 3])
def test_grid_features_equal_the_kernel_at_every_grid_node(dim, rng):
    samples = rng.uniform(-1, 1, (200, dim))
    features = GridFeatures(samples, spacing=0.2, radius=0.3, max_points=10**6)
    phi = features(samples[:40])
    nodes = np.stack(np.unravel_index(np.arange(features.size), features.shape), 1)
    positions = features.low + nodes * features.spacing
    distance = np.linalg.norm(samples[:40, None, :] - positions[None], axis=2)
    expected = sparse_kernel_reference(distance / features.radius)
    dense = np.zeros((40, features.size))
    np.add.at(dense, (np.arange(40)[:, None], phi.columns), phi.values)
    np.testing.assert_allclose(dense, expected, atol=1e-12)


def test_grid_features_refuse_grids_past_the_limit(rng):
    with pytest.raises(ValueError, match="max_grid_points"):
        GridFeatures(rng.uniform(-10, 10, (50, 3)), spacing=0.1, radius=0.15, max_points=1000)


def test_sgd_gives_the_same_weights_for_sparse_and_dense_features(rng):
    points = rng.uniform(-1, 1, (600, 2))
    labels = points[:, 0] > 0.2
    grid = GridFeatures(points, spacing=0.25, radius=0.4, max_points=10**6)

    def dense(batch):
        rows = grid(batch)
        matrix = np.zeros((len(batch), grid.size))
        np.add.at(matrix, (np.arange(len(batch))[:, None], rows.columns), rows.values)
        return matrix

    dense.size = grid.size
    settings = HilbertMapsSettings(batch_size=32, epochs=2, l2=0.0)
    sparse_weights = logistic_sgd(grid, points, labels, settings, np.random.default_rng(1))
    dense_weights = logistic_sgd(dense, points, labels, settings, np.random.default_rng(1))
    np.testing.assert_allclose(sparse_weights, dense_weights, atol=1e-12)
    p = 1 / (1 + np.exp(-(grid(points) @ sparse_weights)))
    assert np.mean((p > 0.5) == labels) > 0.9


def test_sparse_rows_multiply_like_the_dense_matrix():
    rows = SparseRows(np.array([[0, 2], [1, 1]]), np.array([[0.5, 2.0], [1.0, 3.0]]))
    np.testing.assert_allclose(rows @ np.array([1.0, 10.0, 100.0]), [200.5, 40.0])


def test_balanced_subsample_takes_half_of_each_class(rng):
    occupied = np.zeros(1000, dtype=bool)
    occupied[:100] = True
    chosen = balanced_subsample(occupied, 120, rng)
    assert len(np.unique(chosen)) == 120 and occupied[chosen].sum() == 60
    chosen = balanced_subsample(occupied, 400, rng)
    assert occupied[chosen].sum() == 100 and len(chosen) == 400
    assert len(balanced_subsample(occupied, 5000, rng)) == 1000


def test_plsc_recovers_a_known_squashing(rng):
    # Labels drawn from p = Phi(2 mu - 0.5) at zero variance: the fit finds a = 2, b = -0.5.
    from scipy.special import ndtr

    mean = rng.uniform(-2, 2, 20_000)
    targets = np.where(rng.random(20_000) < ndtr(2 * mean - 0.5), 1.0, -1.0)
    a, b = plsc_fit(targets, mean, np.zeros_like(mean))
    assert a == pytest.approx(2.0, abs=0.1) and b == pytest.approx(-0.5, abs=0.05)
