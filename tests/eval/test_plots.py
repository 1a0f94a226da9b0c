"""Pictures of an evaluation."""

import numpy as np
from PIL import Image

from ehm.eval.plots import cost_plot, scan_time_plot, sparsity_plot, write_comparison_plots
from ehm.eval.runner import EvalRecord, summarise


def records() -> list[EvalRecord]:
    """Two methods on two data sets, two fractions, two seeds."""
    made = []
    for dataset in ("room", "lab"):
        for method, f1 in (("a", 0.9), ("b", 0.7)):
            for fraction in (0.8, 0.4):
                for seed in (0, 1):
                    made.append(
                        EvalRecord(dataset, method, fraction, seed, f1, f1 - 0.1 * seed,
                                   0.95, 0.0, 1.0 + seed, 0.1, 10**6, 100, 50)
                    )  # fmt: skip
    return made


def picture(path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"))


def coloured(path) -> int:
    """Pixels of a picture that are neither grey nor black nor white."""
    pixels = picture(path).astype(int)
    return int(np.sum(pixels.max(axis=2) - pixels.min(axis=2) > 60))


def test_every_data_set_gets_a_sparsity_and_a_cost_plot(tmp_path):
    written = write_comparison_plots(summarise(records()), tmp_path / "plots")
    names = [p.name for p in written]
    assert names == ["sparsity_room.png", "cost_room.png", "sparsity_lab.png", "cost_lab.png"]
    for path in written:
        pixels = picture(path)
        assert pixels.shape[1] > 800
        # Drawn, not blank: several colours, most of the picture white background.
        assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20
        assert np.mean(np.all(pixels == 255, axis=2)) > 0.5


def test_plots_draw_one_line_per_method(tmp_path):
    summaries = summarise(records())
    one, two = tmp_path / "one.png", tmp_path / "two.png"
    sparsity_plot([s for s in summaries if s.method == "a"], "room", one)
    sparsity_plot(summaries, "room", two)

    # The second method's lines add coloured pixels.
    assert coloured(two) > 1.3 * coloured(one)
    cost_plot(summaries, "lab", tmp_path / "cost.png")
    assert picture(tmp_path / "cost.png").shape[1] > 800


def test_scan_time_plot_has_one_panel_per_sequence_and_a_line_per_method(tmp_path):
    times = {
        "first": {"ehm": np.full(30, 0.01)},
        "second": {"ehm": np.linspace(0.01, 0.02, 2000), "octomap": np.full(2000, 0.004)},
    }
    scan_time_plot(times, tmp_path / "two.png")
    scan_time_plot({"first": times["first"]}, tmp_path / "one.png")
    assert picture(tmp_path / "two.png").shape[1] > 1.6 * picture(tmp_path / "one.png").shape[1]
    scan_time_plot({"second": {"ehm": times["second"]["ehm"]}}, tmp_path / "alone.png")
    assert coloured(tmp_path / "alone.png") < coloured(tmp_path / "two.png")
