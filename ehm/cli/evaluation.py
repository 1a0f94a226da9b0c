"""`ehm eval`: mapping methods compared on held-out rays."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape

from ehm.cli.app import (
    Force,
    app,
    console,
    errors,
    parse_names,
    parse_numbers,
    progress_bar,
)
from ehm.errors import InputError


@app.command("eval")
def eval_command(
    methods: Annotated[
        str,
        typer.Option(
            help="Comma-separated: octomap hm (= hm-fourier hm-nystrom hm-grid) "
            "lls-hm gpom ehm ehm-alone ehm-realtime ehm-batch, or all."
        ),
    ] = "all",
    datasets: Annotated[
        str,
        typer.Option(
            help="Comma-separated: virtual_room warehouse street dense_room dense_room_noisy "
            "octomap_scan tum_fr2_pioneer_slam2 pcl_room intel_lab icl_living_room "
            "icl_living_room_noisy, or all."
        ),
    ] = "virtual_room",
    fractions: Annotated[str, typer.Option(help="Train fractions of the rays.")] = "0.8,0.6,0.4",
    seeds: Annotated[str, typer.Option(help="Comma-separated seeds of the splits.")] = "0",
    resolution: Annotated[
        float,
        typer.Option(
            help="Map detail, metres: OctoMap's voxel side, EHM's MapConfig.for_resolution and "
            "the test split's margin."
        ),
    ] = 0.05,
    json_path: Annotated[
        Path | None, typer.Option("--json", help="Write one record per run to this JSON file.")
    ] = None,
    plots: Annotated[
        Path | None, typer.Option(help="Write accuracy/F1-against-sparsity and cost PNGs here.")
    ] = None,
    data_dir: Annotated[
        Path | None,
        typer.Option(
            help="Folder of the real data sets (default: $EHM_DATA_DIR or ../shared/data)."
        ),
    ] = None,
    force: Force = False,
) -> None:
    """Compare mapping methods on held-out rays: in each scan a train fraction of the rays
    builds every method, the rest are test points (hits occupied, one free point along each
    ray). Every method is measured on the same split in this process."""
    import json
    import os

    from ehm.eval.baselines import METHODS
    from ehm.eval.datasets import DATASETS
    from ehm.eval.report import summary_table
    from ehm.eval.runner import evaluate_scans, plan_evaluation, summarise
    from ehm.io.output_paths import check_output, check_output_folder

    if json_path is not None:
        check_output(json_path, force=force, suffix=".json")
    if plots is not None:
        check_output_folder(plots)
    if data_dir is not None:
        os.environ["EHM_DATA_DIR"] = str(data_dir)
    fraction_list = parse_numbers(fractions, float, "--fractions")
    seed_list = parse_numbers(seeds, int, "--seeds")
    plan = plan_evaluation(
        parse_names(methods, list(METHODS), "methods"),
        parse_names(datasets, list(DATASETS), "data sets"),
        fraction_list,
        resolution,
        skip_missing=True,
        seeds=seed_list,
    )
    for message in plan.skipped:
        errors.print(f"[yellow]{escape(message)}[/yellow]")
    if not plan.methods or not plan.datasets:
        raise InputError("nothing to evaluate: every method or data set asked for was skipped")

    records = []
    runs = len(plan.datasets) * len(fraction_list) * len(seed_list) * len(plan.methods)
    with progress_bar() as progress:
        task = progress.add_task("evaluating", total=runs)
        for dataset, scans in plan.datasets.items():
            for record in evaluate_scans(
                dataset, scans, list(plan.methods), fraction_list, seed_list, resolution
            ):
                records.append(record)
                description = f"{dataset} {record.fraction:.0%} seed {record.seed}: {record.method}"
                progress.update(task, advance=1, description=description)

    summaries = summarise(records)
    for dataset in plan.datasets:
        table = summary_table(dataset, [s for s in summaries if s.dataset == dataset])
        # Piped or logged output is 80 columns by default: too narrow for the table.
        (console if console.is_terminal else Console(width=140)).print(table)
    for method, description in plan.methods.items():
        console.print(f"[bold]{method}[/bold]: {description}")
    if json_path is not None:
        json_path.write_text(json.dumps([r.to_dict() for r in records], indent=1) + "\n")
        console.print(f"wrote {json_path} ({len(records)} records)")
    if plots is not None:
        from ehm.eval.plots import write_comparison_plots

        for path in write_comparison_plots(summaries, plots):
            console.print(f"wrote {path}")
