"""Pictures of a comparison, off-screen PNGs: accuracy and F1 against sparsity (the paper's
Fig. 9), build and query time and memory per method, integration time per scan."""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike
from pathlib import Path

import numpy as np

from ehm.eval.runner import Summary
from ehm.viz.pictures import pyplot

# Methods that score alike (EHM scan by scan or in one batch, on one scan) stay apart.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


def sparsity_plot(summaries: Sequence[Summary], dataset: str, path: str | PathLike[str]) -> None:
    """Accuracy and F1 at 0.5 against the share of rays held out, one line per method, mean
    over seeds with their standard deviation as error bars."""
    plt = pyplot()
    rows = [s for s in summaries if s.dataset == dataset]
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharex=True)
    for i, method in enumerate(dict.fromkeys(s.method for s in rows)):
        mine = sorted((s for s in rows if s.method == method), key=lambda s: -s.fraction)
        held_out = [round(100 * (1 - s.fraction)) for s in mine]
        for axis, measure in zip(axes, ("accuracy", "f1"), strict=True):
            axis.errorbar(
                held_out,
                [s.mean[measure] for s in mine],
                yerr=[s.std[measure] for s in mine],
                marker=MARKERS[i % len(MARKERS)],
                linestyle="-" if i % 2 == 0 else "--",
                capsize=3,
                label=method,
            )
    for axis, title in zip(axes, ("accuracy at p = 0.5", "F1 of the occupied class"), strict=True):
        axis.set_title(f"{dataset}: {title}")
        axis.set_xlabel("rays held out (%)")
        axis.grid(alpha=0.3)
    axes[1].legend(loc="lower left", fontsize=8)
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)


def cost_plot(summaries: Sequence[Summary], dataset: str, path: str | PathLike[str]) -> None:
    """Build time, query time and memory per method at the largest train fraction, bars on
    logarithmic axes."""
    plt = pyplot()
    rows = [s for s in summaries if s.dataset == dataset]
    largest = max(s.fraction for s in rows)
    rows = [s for s in rows if s.fraction == largest]
    names = [s.method for s in rows]
    figure, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    panels = (("build_s", "build (s)", 1.0), ("query_s", "query (s)", 1.0))
    panels += (("memory_bytes", "memory (MB)", 1e-6),)
    for axis, (measure, label, scale) in zip(axes, panels, strict=True):
        axis.bar(names, [scale * s.mean[measure] for s in rows], color="tab:blue")
        axis.set_yscale("log")
        axis.set_title(f"{dataset}, train {largest:.0%}: {label}")
        axis.tick_params(axis="x", rotation=45)
        axis.grid(alpha=0.3, axis="y")
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)


def scan_time_plot(
    seconds: dict[str, dict[str, Sequence[float]]], path: str | PathLike[str]
) -> None:
    """Time per scan against scan index, one panel per sequence and one line per method:
    seconds[sequence][method] is (n_scans,) seconds. Sequences of more than 200 scans show
    the median of every 25 scans, so the trend stands out of the noise."""
    plt = pyplot()
    figure, axes = plt.subplots(1, len(seconds), figsize=(5.5 * len(seconds), 3.8), squeeze=False)
    for axis, (name, methods) in zip(axes[0], seconds.items(), strict=True):
        for i, (method, times) in enumerate(methods.items()):
            milliseconds = 1000 * np.asarray(times)
            index = np.arange(len(milliseconds))
            if len(milliseconds) > 200:
                window = len(milliseconds) // 25 * 25
                milliseconds = np.median(milliseconds[:window].reshape(-1, 25), axis=1)
                index = np.arange(len(milliseconds)) * 25 + 12
            axis.plot(
                index, milliseconds, marker=MARKERS[i] if len(index) < 50 else "", label=method
            )
        axis.set_title(f"{name}: time per scan")
        axis.set_xlabel("scan index")
        axis.set_ylabel("time (ms)")
        axis.set_ylim(bottom=0)
        axis.legend()
        axis.grid(alpha=0.3)
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)


def write_comparison_plots(summaries: Sequence[Summary], folder: str | PathLike[str]) -> list[Path]:
    """sparsity_<dataset>.png and cost_<dataset>.png for each data set; returns the paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for dataset in dict.fromkeys(s.dataset for s in summaries):
        for name, draw in (("sparsity", sparsity_plot), ("cost", cost_plot)):
            path = folder / f"{name}_{dataset}.png"
            draw(summaries, dataset, path)
            written.append(path)
    return written
