"""Every method on the same held-out-rays splits, in one process: the comparison of the
paper's Section 4.

    records = ehm.evaluate(["virtual_room"], ["octomap", "ehm"], fractions=(0.8, 0.4))
    for record in records:
        print(record.method, record.fraction, record.f1)

For each data set, train fraction and seed, one split (ehm.eval.protocol.held_out_rays) serves every
method; each method is built from the split's training scans and queried at its test points.
Build and query times are wall-clock seconds; the first build of each method in the process
is preceded by an untimed one on a tiny scan, so compilation is not timed.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, fields

import numpy as np

from ehm.config import DEFAULT_RESOLUTION
from ehm.core.sensor.scan import Scan
from ehm.errors import InputError
from ehm.eval.baselines import METHODS, Mapper, make_mapper, method_names
from ehm.eval.datasets import DATASETS, DataMissingError, load_dataset
from ehm.eval.metrics import score
from ehm.eval.protocol import held_out_rays

DEFAULT_FRACTIONS = (0.8, 0.6, 0.4)


@dataclass(frozen=True)
class EvalRecord:
    """One method on one split. accuracy, f1 (occupied class) at 0.5, auc (ROC), unknown
    (share of test points at exactly 0.5); build_s and query_s in seconds; memory_bytes of
    the built map; n_train training rays; n_test test points."""

    dataset: str
    method: str
    fraction: float
    seed: int
    accuracy: float
    f1: float
    auc: float
    unknown: float
    build_s: float
    query_s: float
    memory_bytes: int
    n_train: int
    n_test: int

    def to_dict(self) -> dict[str, float | int | str]:
        return asdict(self)


RECORD_KEYS = tuple(f.name for f in fields(EvalRecord))

_warmed_up: set[tuple[str, int]] = set()


# Rays of each of the two scans a warm-up learns, and their length, metres: a batch's worth
# (MapConfig.batch_rays), so the second is learned with the first's evidence in the memory,
# and enough samples that the evidence is gathered in parts and SGD steps two sides, as a
# LiDAR sweep's are.
WARM_UP_RAYS = 20_000
WARM_UP_RANGE = 6.0


def warm_up(method: str, dim: int) -> None:
    """Build and query `method` once on two small scans, untimed (compiles Numba kernels,
    those that learn a scan with the evidence of the one before too)."""
    if (method, dim) in _warmed_up:
        return
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(WARM_UP_RAYS, dim))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    scans = [
        Scan(WARM_UP_RANGE * directions + origin, origin)
        for origin in (np.zeros(dim), np.full(dim, 0.5))
    ]
    mapper = make_mapper(method, DEFAULT_RESOLUTION, 0)
    mapper.build(scans)
    mapper.occupancy(directions)
    _warmed_up.add((method, dim))


def run_method(
    mapper: Mapper, train: list[Scan], points: np.ndarray
) -> tuple[np.ndarray, float, float]:
    """Build `mapper` from `train` and query it at `points`: (probabilities, build s,
    query s)."""
    start = time.perf_counter()
    mapper.build(train)
    built = time.perf_counter()
    probability = mapper.occupancy(points)
    return probability, built - start, time.perf_counter() - built


def evaluate_scans(
    dataset: str,
    scans: list[Scan],
    methods: Sequence[str],
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    seeds: Sequence[int] = (0,),
    resolution: float = DEFAULT_RESOLUTION,
    on_mapper: Callable[[EvalRecord, Mapper], None] | None = None,
) -> Iterator[EvalRecord]:
    """One EvalRecord per (fraction, seed, method), in that order, as each is measured.
    `on_mapper(record, mapper)`, when given, sees each built mapper (for per-scan times)."""
    methods = method_names(list(methods))
    for method in methods:
        warm_up(method, scans[0].dim)
    for fraction in fractions:
        for seed in seeds:
            split = held_out_rays(scans, fraction, resolution, seed)
            n_train = sum(len(s) for s in split.train)
            for method in methods:
                mapper = make_mapper(method, resolution, seed)
                probability, build_s, query_s = run_method(mapper, split.train, split.points)
                s = score(split.occupied, probability, probability == 0.5)
                record = EvalRecord(
                    dataset,
                    method,
                    fraction,
                    seed,
                    s.accuracy,
                    s.f1,
                    s.auc,
                    s.unknown,
                    build_s,
                    query_s,
                    mapper.memory_bytes(),
                    n_train,
                    len(split.points),
                )
                if on_mapper is not None:
                    on_mapper(record, mapper)
                yield record


def check_request(
    methods: Sequence[str],
    datasets: Sequence[str],
    fractions: Sequence[float],
    seeds: Sequence[int] = (0,),
    resolution: float = DEFAULT_RESOLUTION,
) -> list[str]:
    """The methods with group names expanded, once every name and number is checked:
    InputError names unknown methods or data sets, fractions outside (0, 1), negative seeds
    and a resolution that is not a positive number of metres."""
    unknown = [d for d in datasets if d not in DATASETS]
    if unknown:
        raise InputError(f"unknown data set(s) {', '.join(unknown)}; known: {', '.join(DATASETS)}")
    for fraction in fractions:
        if not 0.0 < fraction < 1.0:
            raise InputError(f"train fractions must be in (0, 1), got {fraction}")
    for seed in seeds:
        if not (isinstance(seed, int) and seed >= 0):
            raise InputError(f"seeds must be integers >= 0, got {seed!r}")
    if not 0.0 < resolution < float("inf"):
        raise InputError(f"resolution must be a positive number of metres, got {resolution!r}")
    return method_names(list(methods))


@dataclass(frozen=True)
class EvalPlan:
    """An evaluation ready to run. methods: names, each with its one-line description;
    datasets: the scans of each data set by name; skipped: why methods or data sets were left
    out (bindings or files missing), one message each."""

    methods: dict[str, str]
    datasets: dict[str, list[Scan]]
    skipped: list[str]


def plan_evaluation(
    methods: Sequence[str],
    datasets: Sequence[str],
    fractions: Sequence[float],
    resolution: float = DEFAULT_RESOLUTION,
    skip_missing: bool = False,
    seeds: Sequence[int] = (0,),
) -> EvalPlan:
    """Check the request (see check_request), then make one mapper of each method (at
    `resolution` metres) and load each data set. A method whose bindings are missing
    (ImportError) or a data set whose files are absent (DataMissingError) raises, or with
    `skip_missing` is left out with a message."""
    descriptions: dict[str, str] = {}
    loaded: dict[str, list[Scan]] = {}
    skipped: list[str] = []
    for method in check_request(methods, datasets, fractions, seeds, resolution):
        try:
            descriptions[method] = make_mapper(method, resolution, 0).description
        except ImportError as error:
            if not skip_missing:
                raise
            skipped.append(f"skipped {method}: {error}")
    for dataset in datasets:
        try:
            loaded[dataset] = load_dataset(dataset)
        except DataMissingError as error:
            if not skip_missing:
                raise
            skipped.append(f"skipped {dataset}: {error}")
    return EvalPlan(descriptions, loaded, skipped)


def evaluate(
    datasets: Sequence[str] = ("virtual_room",),
    methods: Sequence[str] = tuple(METHODS),
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    seeds: Sequence[int] = (0,),
    resolution: float = DEFAULT_RESOLUTION,
) -> list[EvalRecord]:
    """The held-out-rays comparison of `methods` (names of ehm.eval.baselines.METHODS, or
    'hm') on `datasets` (names of ehm.eval.datasets.DATASETS) at every train fraction and seed.

    Raises InputError for unknown names, fractions outside (0, 1), negative seeds,
    DataMissingError when a real data set's files are absent, ImportError when the OctoMap
    bindings are.
    """
    plan = plan_evaluation(methods, datasets, fractions, resolution, seeds=seeds)
    records: list[EvalRecord] = []
    for dataset, scans in plan.datasets.items():
        records += evaluate_scans(dataset, scans, list(plan.methods), fractions, seeds, resolution)
    return records


@dataclass(frozen=True)
class Summary:
    """The records of one (dataset, method, fraction) over seeds: mean and standard
    deviation over seeds (0 for one seed) of each measure, by record field name."""

    dataset: str
    method: str
    fraction: float
    n_seeds: int
    mean: dict[str, float]
    std: dict[str, float]

    def format(self, measure: str, scale: float = 1.0, digits: int = 3) -> str:
        """'mean±std' of `measure` times `scale` (only the mean for one seed)."""
        text = f"{scale * self.mean[measure]:,.{digits}f}"
        if self.n_seeds > 1:
            text += f"±{scale * self.std[measure]:,.{digits}f}"
        return text


MEASURES = ("accuracy", "f1", "auc", "unknown", "build_s", "query_s", "memory_bytes")


def summarise(records: Sequence[EvalRecord]) -> list[Summary]:
    """Records grouped by (dataset, method, fraction), in the order they first appear."""
    groups: dict[tuple[str, str, float], list[EvalRecord]] = {}
    for record in records:
        groups.setdefault((record.dataset, record.method, record.fraction), []).append(record)
    summaries = []
    for (dataset, method, fraction), group in groups.items():
        values = {m: [float(getattr(r, m)) for r in group] for m in MEASURES}
        summaries.append(
            Summary(
                dataset,
                method,
                fraction,
                len(group),
                {m: statistics.fmean(v) for m, v in values.items()},
                {m: statistics.stdev(v) if len(v) > 1 else 0.0 for m, v in values.items()},
            )
        )
    return summaries
