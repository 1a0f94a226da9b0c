"""The paper's Section 4 re-run on data anyone can get, every method in one process on the
same held-out-rays splits: Table 3, Figure 9, Table 4, Table 5, memory per method, and every
method on every data set (time per scan against the scans in the map: scan_times.py).

    python benchmarks/paper_evaluation.py [--seeds 3]

Rewrites its section of BENCHMARKS.md (between the paper-evaluation markers, appended when
missing), draws Figure 9 into docs/images/ (the docs show it too) and writes every record to
benchmarks/results/paper_evaluation_records.json. Data sets whose files are absent are left out,
with a line saying so.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Sequence
from datetime import date
from pathlib import Path

from common import markdown_table
from results_file import run_recorded

from ehm.eval.baselines import METHODS, make_mapper
from ehm.eval.datasets import DATASETS, DataMissingError, load_dataset
from ehm.eval.plots import sparsity_plot
from ehm.eval.runner import DEFAULT_FRACTIONS, EvalRecord, Summary, evaluate_scans, summarise

HERE = Path(__file__).resolve().parent
BEGIN, END = "<!-- paper-evaluation:begin -->", "<!-- paper-evaluation:end -->"


class Runs:
    """Records by (dataset, method, fraction, seed), measured once each."""

    def __init__(self) -> None:
        self.records: dict[tuple[str, str, float, int], EvalRecord] = {}
        self.scans: dict[str, list] = {}
        self.missing: dict[str, str] = {}

    def load(self, dataset: str) -> bool:
        if dataset not in self.scans and dataset not in self.missing:
            try:
                self.scans[dataset] = load_dataset(dataset)
            except DataMissingError as error:
                self.missing[dataset] = str(error)
        return dataset in self.scans

    def measure(
        self, dataset: str, methods: Sequence[str], fractions: Sequence[float], seeds: Sequence[int]
    ) -> list[EvalRecord]:
        if not self.load(dataset):
            return []
        for fraction in fractions:
            for seed in seeds:
                todo = [m for m in methods if (dataset, m, fraction, seed) not in self.records]
                if not todo:
                    continue
                for record in evaluate_scans(
                    dataset, self.scans[dataset], todo, [fraction], [seed]
                ):
                    print(
                        f"  {dataset} {fraction:.0%} seed {seed} {record.method}: "
                        f"F1 {record.f1:.3f}, build {record.build_s:.2f} s",
                        file=sys.stderr,
                        flush=True,
                    )
                    self.records[(dataset, record.method, fraction, seed)] = record
        return [self.records[(dataset, m, f, s)] for f in fractions for s in seeds for m in methods]


def find(summaries: Sequence[Summary], method: str, fraction: float) -> Summary:
    return next(s for s in summaries if s.method == method and s.fraction == fraction)


def table_3(runs: Runs, seeds: Sequence[int], figures: Path) -> str:
    """Times and memory per method (Table 3), accuracy and F1 against sparsity (Fig. 9)."""
    records = runs.measure("virtual_room", list(METHODS), DEFAULT_FRACTIONS, seeds)
    summaries = summarise(records)
    sparsity_plot(summaries, "virtual_room", figures / "fig9_virtual_room.png")
    n_test = records[0].n_test
    text = (
        f"### Table 3: training and query time per method, virtual room\n\n"
        f"Train fraction 0.8 ({records[0].n_train:,} rays), {n_test:,} test points queried at "
        f"once; mean ± standard deviation over seeds {list(seeds)}. Memory is what the built "
        "map keeps (OctoMap: memoryUsage()). The room is one scan, so `ehm` and `ehm-batch` "
        "do the same work here.\n\n"
    )
    rows = [
        [
            s.method,
            s.format("build_s", 1000, 0),
            s.format("query_s", 1000, 0),
            s.format("memory_bytes", 1e-6, 2),
        ]
        for s in summaries
        if s.fraction == 0.8
    ]
    text += markdown_table(["method", "training ms", "query ms", "memory MB"], rows)
    text += (
        "\n### Figure 9: accuracy and F1 against sparsity, virtual room\n\n"
        "![accuracy and F1 against the share of rays held out](docs/images/"
        "fig9_virtual_room.png)\n\n"
    )
    rows = []
    for method in METHODS:
        cells = [method]
        for measure in ("accuracy", "f1"):
            cells += [find(summaries, method, f).format(measure) for f in DEFAULT_FRACTIONS]
        rows.append(cells)
    header = ["method"] + [f"{m} {f:.0%}" for m in ("accuracy", "F1") for f in DEFAULT_FRACTIONS]
    return text + markdown_table(header, rows)


def method_table(
    runs: Runs, dataset: str, methods: tuple[str, ...], seeds: Sequence[int], title: str
) -> str:
    """Build and query time and F1 at every fraction for a few methods (Tables 4 and 5)."""
    records = runs.measure(dataset, list(methods), DEFAULT_FRACTIONS, seeds)
    if not records:
        return f"### {title}\n\nLeft out: {runs.missing[dataset]}\n"
    summaries = summarise(records)
    largest = max(DEFAULT_FRACTIONS)
    rows = [
        ["training ms (train 80 %)"]
        + [find(summaries, m, largest).format("build_s", 1000, 0) for m in methods],
        ["query ms (train 80 %)"]
        + [find(summaries, m, largest).format("query_s", 1000, 0) for m in methods],
        ["memory MB (train 80 %)"]
        + [find(summaries, m, largest).format("memory_bytes", 1e-6, 2) for m in methods],
    ]
    for fraction in DEFAULT_FRACTIONS:
        rows.append(
            [f"F1 ({fraction:.0%})"] + [find(summaries, m, fraction).format("f1") for m in methods]
        )
    for fraction in DEFAULT_FRACTIONS:
        rows.append(
            [f"ROC-AUC ({fraction:.0%})"]
            + [find(summaries, m, fraction).format("auc") for m in methods]
        )
    scans = runs.scans[dataset]
    return (
        f"### {title}\n\n{len(scans)} scan{'s' if len(scans) > 1 else ''}, "
        f"{sum(len(s) for s in scans):,} rays; "
        f"mean ± standard deviation over seeds {list(seeds)}.\n\n"
        + markdown_table(["measure", *methods], rows)
    )


def every_dataset(runs: Runs) -> str:
    """Every method on every data set at train fraction 0.8, seed 0."""
    text = "### Every method on every data set, train fraction 0.8, seed 0\n\n"
    rows = []
    for dataset in DATASETS:
        for record in runs.measure(dataset, list(METHODS), [0.8], [0]):
            rows.append(
                [
                    dataset,
                    record.method,
                    f"{record.accuracy:.3f}",
                    f"{record.f1:.3f}",
                    f"{record.auc:.3f}",
                    f"{record.unknown:.3f}",
                    f"{record.build_s:.2f}",
                    f"{record.query_s:.2f}",
                    f"{record.memory_bytes / 1e6:.2f}",
                ]
            )
    header = ["data set", "method", "accuracy", "F1", "ROC-AUC", "unknown", "build s", "query s"]
    text += markdown_table([*header, "memory MB"], rows, text_columns=2)
    for dataset, reason in runs.missing.items():
        text += f"\nLeft out {dataset}: {reason}\n"
    return text


def replace_section(document: str, section: str) -> str:
    block = f"{BEGIN}\n{section}{END}"
    if BEGIN in document and END in document:
        head, rest = document.split(BEGIN, 1)
        return head + block + rest.split(END, 1)[1]
    return document.rstrip("\n") + "\n\n" + block + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="Splits per fraction (seeds 0..n-1).")
    parser.add_argument("--output", type=Path, default=HERE.parent / "BENCHMARKS.md")
    args = parser.parse_args()
    seeds = list(range(args.seeds))
    figures, results = HERE.parent / "docs" / "images", HERE / "results"
    figures.mkdir(exist_ok=True)
    results.mkdir(exist_ok=True)

    start = time.perf_counter()
    runs = Runs()
    parts = [
        table_3(runs, seeds, figures),
        method_table(
            runs,
            "octomap_scan",
            ("octomap", "ehm"),
            seeds,
            "Table 4: EHM against OctoMap on the single real scan (octomap_scan)",
        ),
        method_table(
            runs,
            "tum_fr2_pioneer_slam2",
            ("ehm-batch", "ehm", "ehm-alone"),
            seeds,
            "Table 5: single batch against incremental on the TUM sequence (`ehm`: with the "
            "sample memory; `ehm-alone`: each scan learned alone, as the paper's Alg. 2)",
        ),
        every_dataset(runs),
    ]
    minutes = (time.perf_counter() - start) / 60
    descriptions = "".join(f"- `{m}`: {make_mapper(m, 0.05, 0).description}\n" for m in METHODS)
    machine = f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
    section = (
        "## The paper's evaluation (Sec. 4): every method on held-out rays\n\n"
        f"Command: `.venv/bin/python benchmarks/paper_evaluation.py --seeds {args.seeds}`, "
        f"{date.today()}, {machine}, {minutes:.0f} min. Protocol of DESIGN.md: in each scan "
        "a train fraction of the rays builds every method, the rest are test points (each "
        "held-out hit occupied, one free point uniform along each held-out ray up to 2 "
        "resolutions before its end); accuracy and F1 at p = 0.5, unknown = share of test "
        "points at exactly 0.5. Build = everything a method does before it can answer. "
        "Resolution 0.05 m. Records: benchmarks/results/paper_evaluation_records.json.\n\n"
        f"Methods:\n\n{descriptions}\n" + "\n".join(parts)
    )
    args.output.write_text(replace_section(args.output.read_text(), section))
    records = [r.to_dict() for r in runs.records.values()]
    (results / "paper_evaluation_records.json").write_text(json.dumps(records, indent=1) + "\n")
    print(f"wrote {args.output}, {figures}, {results} in {minutes:.1f} min")


if __name__ == "__main__":
    run_recorded(main, __file__)
