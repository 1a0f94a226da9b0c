"""Tables of an evaluation, for the terminal (Rich)."""

from __future__ import annotations

from collections.abc import Sequence

from rich import box
from rich.table import Table

from ehm.eval.runner import Summary


def summary_table(dataset: str, summaries: Sequence[Summary]) -> Table:
    """One row per (method, train fraction) of `dataset`: mean (±std over seeds) of each
    measure."""
    n_seeds = max(s.n_seeds for s in summaries)
    spread = f"mean±std over {n_seeds} seeds" if n_seeds > 1 else "one seed"
    table = Table(title=f"{dataset}: held-out rays, {spread}", box=box.SIMPLE_HEAD)
    columns = ("method", "train", "accuracy", "F1", "ROC-AUC", "unknown", "build s", "query s")
    for column in (*columns, "memory MB"):
        table.add_column(column, justify="left" if column == "method" else "right", no_wrap=True)
    for s in summaries:
        table.add_row(
            s.method,
            f"{s.fraction:.0%}",
            *(s.format(m) for m in ("accuracy", "f1", "auc", "unknown")),
            s.format("build_s", digits=2),
            s.format("query_s", digits=2),
            s.format("memory_bytes", 1e-6, 2),
        )
    return table
