"""Fixtures shared by every test: the synthetic scenes, maps of them, and the real data sets."""

import os
from pathlib import Path

import numpy as np
import pytest

import ehm
from ehm.config import MapConfig
from ehm.core.model.clusters import ClusterSet
from ehm.eval.datasets import floor_plan_2d, virtual_room
from ehm.eval.datasets.real import DataMissingError
from ehm.eval.guide_files import write_carmen_log

# The shared data folder beside the project's checkout, wherever pytest runs from.
os.environ.setdefault("EHM_DATA_DIR", str(Path(__file__).resolve().parents[2] / "shared" / "data"))


@pytest.fixture(scope="session")
def room():
    return virtual_room(seed=0)


@pytest.fixture(scope="session")
def plan():
    return floor_plan_2d(seed=0)


@pytest.fixture(scope="session")
def plan_log(tmp_path_factory, plan):
    """The floor plan's scans as a CARMEN log of 180 beams each, from -90 to +89 degrees."""
    log = tmp_path_factory.mktemp("plan_log") / "plan.log"
    write_carmen_log(plan.scans, log)
    return log


@pytest.fixture(scope="session")
def room_map(room):
    """The virtual room in one fit, default settings (tests must not change it)."""
    return ehm.HilbertMap().fit(room.scans)


@pytest.fixture
def rng():
    return np.random.default_rng(42)


@pytest.fixture
def real_data():
    """Runs a real-data loader, skipping the test with its message when the data is absent."""

    def load(loader):
        try:
            return loader()
        except DataMissingError as missing:
            pytest.skip(str(missing))

    return load


@pytest.fixture
def random_clusters():
    """Makes n random 3D clusters in a cube of side `extent` metres: a fifth coarse, half
    occupied, some planar (planar kernels on)."""

    def make(rng, n=400, extent=6.0):
        clusters = ClusterSet.empty(3)
        spread = rng.normal(size=(n, 3, 3)) * rng.uniform(0.02, 0.15, (n, 1, 1))
        clusters.append(
            rng.uniform(0, extent, (n, 3)),
            spread @ np.swapaxes(spread, 1, 2),
            np.full(n, 10),
            rng.random(n) < 0.2,
            rng.random(n) < 0.5,
        )
        clusters.refresh(np.arange(n), MapConfig(planar_kernel=True, planar_ratio=0.3))
        return clusters

    return make


@pytest.fixture
def sparse_batch():
    """Makes a random batch of n samples' sparse features over n_clusters clusters, up to k
    per sample (groups of samples share k clusters, one group fewer, 30 % of the values
    zero), as compressed rows: indptr (n + 1,), rows (nnz,), values (nnz,) (see
    SparseFeatures), and labels (n,) 0 or 1, two fifths occupied."""

    def make(rng, n=300, k=5, n_groups=25, n_clusters=40):
        values = rng.uniform(0, 1, (n, k)) * (rng.random((n, k)) < 0.7)
        group_of_point = rng.integers(0, n_groups, n)
        neighbours = np.array([rng.choice(n_clusters, k, replace=False) for _ in range(n_groups)])
        neighbours[3, 2:] = -1
        labels = (rng.random(n) < 0.4).astype(float)
        clusters = neighbours[group_of_point]
        kept = (clusters >= 0) & (values != 0.0)
        indptr = np.concatenate([[0], np.cumsum(kept.sum(axis=1))])
        return indptr, clusters[kept], values[kept], labels

    return make


@pytest.fixture
def table_row():
    """The cells after the first of the Rich table row of a command's output that starts
    with `name`: table_row(output, name)."""

    def cells(output: str, name: str) -> list[str]:
        for line in output.splitlines():
            row = [c.strip() for c in line.strip("│┃| ").split("│")]
            if row and row[0] == name:
                return row[1:]
        raise AssertionError(f"no row {name!r} in:\n{output}")

    return cells
