"""Tables of an evaluation."""

from rich.console import Console

from ehm.eval.report import summary_table
from ehm.eval.runner import EvalRecord, summarise


def rendered(table) -> str:
    console = Console(width=200, record=True)
    console.print(table)
    return console.export_text()


def test_one_row_per_method_and_fraction_with_spread_over_seeds():
    records = [
        EvalRecord("room", "ehm", 0.8, seed, 0.9, f1, 0.95, 0.0, 2.0, 0.5, 4_500_000, 10, 20)
        for seed, f1 in ((0, 0.8), (1, 0.9))
    ]
    text = rendered(summary_table("room", summarise(records)))
    assert "room: held-out rays, mean±std over 2 seeds" in text
    (row,) = [line for line in text.splitlines() if line.strip().startswith("ehm")]
    assert row.split() == [
        "ehm", "80%", "0.900±0.000", "0.850±0.071", "0.950±0.000", "0.000±0.000", "2.00±0.00",
        "0.50±0.00", "4.50±0.00",
    ]  # fmt: skip
    one_seed = rendered(summary_table("room", summarise(records[:1])))
    assert "one seed" in one_seed and "±" not in one_seed.split("memory MB")[1]
