"""The `ehm` command: demo, map, query, grid, mesh, render, info, eval. Heavy imports happen inside
each command so that `ehm --help` is instant."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

app = typer.Typer(
    help="Efficient Hilbert Maps: continuous occupancy maps from range scans.",
    no_args_is_help=True,
    rich_markup_mode="rich",
)
console = Console()

Resolution = Annotated[float, typer.Option(help="Voxel side of the grid, metres.")]
Bounds = Annotated[
    str | None,
    typer.Option(
        help="Grid box 'x0,y0,z0,x1,y1,z1' (2D: 'x0,y0,x1,y1'), metres; default: all of the map."
    ),
]
MaxGiB = Annotated[float, typer.Option(help="Refuse grids larger than this, GiB.")]
Level = Annotated[float, typer.Option(help="Occupancy probability of the surface.")]


def _parse_settings(settings: list[str]) -> dict:
    """`name=value` pairs into MapConfig overrides, values typed like the defaults."""
    from ehm.config import MapConfig

    defaults = MapConfig().to_dict()
    overrides = {}
    for item in settings:
        name, sep, value = item.partition("=")
        if not sep or name not in defaults:
            raise typer.BadParameter(f"{item!r}: expected name=value with a MapConfig name")
        kind = type(defaults[name])
        if kind is bool:
            words = {"1": True, "true": True, "yes": True, "on": True}
            words |= {"0": False, "false": False, "no": False, "off": False}
            if value.lower() not in words:
                raise typer.BadParameter(f"{item!r}: {name} is true or false, got {value!r}")
            overrides[name] = words[value.lower()]
        else:
            try:
                overrides[name] = kind(value)
            except ValueError as error:
                raise typer.BadParameter(
                    f"{item!r}: {name} is a{'n' if kind is int else ''} {kind.__name__}, "
                    f"got {value!r}"
                ) from error
    return overrides


def _load_or_fail(path: Path):
    """The map at `path`, or a one-line error and exit status 1."""
    from ehm.hilbert_map import load
    from ehm.io.map_file import MapFileError

    try:
        return load(path)
    except (MapFileError, FileNotFoundError) as error:
        console.print(f"[red]error:[/red] {error}")
        raise typer.Exit(1) from error


def _grid_or_fail(
    hilbert_map, bounds: str | None, resolution: float, max_gib: float, std: bool = False
):
    """The map's grid over `bounds` ('x0,y0,..' text), with the std when asked, or a usage
    error naming the problem."""
    import numpy as np

    try:
        box = None
        if bounds is not None:
            box = np.array([float(v) for v in bounds.split(",")])
            if len(box) != 2 * hilbert_map.dim:
                raise ValueError(
                    f"bounds need {2 * hilbert_map.dim} numbers for a {hilbert_map.dim}D map, "
                    f"got {len(box)}"
                )
            box = box.reshape(2, hilbert_map.dim)
        return hilbert_map.grid(box, resolution, max_bytes=int(max_gib * 2**30), std=std)
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error


def _progress():
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    return Progress(
        "[progress.description]{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
    )


def _timings_table(title: str, seconds: dict[str, float]) -> Table:
    table = Table(title=title)
    table.add_column("stage")
    table.add_column("time (ms)", justify="right")
    for stage, value in seconds.items():
        table.add_row(stage, f"{1000 * value:.1f}")
    table.add_row("[bold]total", f"[bold]{1000 * sum(seconds.values()):.1f}")
    return table


@app.command()
def demo(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Folder for the map and pictures.")
    ] = Path("ehm_demo"),
    seed: Annotated[int, typer.Option(help="Seed of the simulation and the map.")] = 0,
) -> None:
    """Simulate the virtual room, map it, score the map against the exact occupancy, and write
    the map, occupancy slices, a mesh (PLY) and a picture of the mesh."""
    from ehm.eval.demo import run_demo
    from ehm.pipeline import ProgressBar

    result = run_demo(out, seed, [ProgressBar(console)])
    table = Table(title="Accuracy against the exact occupancy of the virtual room")
    for column in ("test points", "n", "occupied", "accuracy", "F1", "ROC-AUC"):
        table.add_column(column, justify="right" if column != "test points" else "left")
    for name, exact in result.exact.items():
        s = exact.scores
        table.add_row(
            name, f"{exact.n}", f"{exact.occupied:.1%}", f"{s.accuracy:.3f}", f"{s.f1:.3f}",
            f"{s.auc:.3f}",
        )  # fmt: skip
    hilbert_map = result.run.hilbert_map
    console.print(table)
    console.print(_timings_table("Integrate, per stage (Table 2)", result.run.stage_seconds))
    console.print(_timings_table("Demo, per step", result.steps))
    console.print(
        f"{hilbert_map!r}: {hilbert_map.memory_bytes() / 1e6:.2f} MB from "
        f"{result.run.n_rays} rays; {result.grid!r}; mesh of {result.n_faces} faces"
    )
    for path in result.written:
        console.print(f"wrote {path}")


@app.command("map")
def map_command(
    inputs: Annotated[list[Path], typer.Argument(help="Scan files or a TUM folder.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Map file to write.")],
    format: Annotated[
        str | None,
        typer.Option("--format", "-f", help="Reader: xyz ply pcd kitti graph tum carmen."),
    ] = None,
    origin: Annotated[
        str | None, typer.Option(help="Sensor origin 'x,y,z' for single point clouds.")
    ] = None,
    poses: Annotated[Path | None, typer.Option(help="Poses file for KITTI .bin scans.")] = None,
    batch: Annotated[bool, typer.Option(help="Learn all scans at once (single batch).")] = False,
    resolution: Annotated[
        float,
        typer.Option(
            help="Map detail, metres: scales every length setting (MapConfig.for_resolution); "
            "about 0.2 for long-range outdoor LiDAR."
        ),
    ] = 0.05,
    setting: Annotated[
        list[str] | None, typer.Option("--set", help="MapConfig override name=value.")
    ] = None,
) -> None:
    """Build a map from scans of any supported format and save it."""
    from ehm.config import MapConfig
    from ehm.hilbert_map import HilbertMap
    from ehm.io.readers import read_scans
    from ehm.pipeline import MappingPipeline, ProgressBar

    try:
        sensor = _numbers(origin, float, "--origin") if origin else None
        config = MapConfig.for_resolution(resolution, **_parse_settings(setting or []))
        hilbert_map = HilbertMap(config)
        scans = read_scans(inputs, format=format, origin=sensor, poses=poses)
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error
    run = MappingPipeline(scans, hilbert_map, batch, [ProgressBar(console)]).run()
    hilbert_map.save(output)
    console.print(_timings_table("Mapping, per stage", run.stage_seconds))
    console.print(
        f"{run.n_scans} scans, {run.n_rays} rays ({run.n_dropped} non-finite dropped) -> "
        f"{hilbert_map!r}, {hilbert_map.memory_bytes() / 1e6:.2f} MB, mapped in "
        f"{run.seconds:.1f} s; wrote {output}"
    )


@app.command()
def query(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    points: Annotated[Path, typer.Argument(help="Points: .npy (n, d) or .csv with d columns.")],
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write .npy or .csv; default stdout.")
    ] = None,
    mode: Annotated[str | None, typer.Option(help="batch or exact.")] = None,
    std: Annotated[
        bool, typer.Option("--std", help="Also the standard deviation: columns p, std.")
    ] = False,
) -> None:
    """Occupancy probability of each point (and with --std its standard deviation)."""
    import numpy as np

    hilbert_map = _load_or_fail(map_path)
    if points.suffix == ".npy":
        query_points = np.load(points)
    else:
        query_points = np.loadtxt(points, delimiter=",", ndmin=2, comments="#")
    try:
        answers = hilbert_map.occupancy(query_points, mode=mode, return_std=std)
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error
    columns = np.column_stack(answers) if std else answers
    if output is None:
        typer.echo("\n".join(",".join(f"{v:.6f}" for v in np.atleast_1d(row)) for row in columns))
    elif output.suffix == ".npy":
        np.save(output, columns)
    else:
        np.savetxt(output, columns, fmt="%.6f", delimiter=",")


@app.command()
def grid(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Grid file to write (.npz).")],
    resolution: Resolution = 0.05,
    bounds: Bounds = None,
    max_gib: MaxGiB = 1.0,
    std: Annotated[
        bool, typer.Option("--std", help="Also the standard deviation of each voxel.")
    ] = False,
) -> None:
    """Occupancy grid of a map (incremental grid reconstruction), saved as .npz with arrays
    probability, scores, origin, resolution and intercept (and with --std, std)."""
    from ehm.io.grid_file import save_grid

    hilbert_map = _load_or_fail(map_path)
    occupancy_grid = _grid_or_fail(hilbert_map, bounds, resolution, max_gib, std)
    save_grid(occupancy_grid, output)
    console.print(f"{occupancy_grid!r}\nwrote {output}")


@app.command()
def mesh(
    map_path: Annotated[Path, typer.Argument(help="Map file (3D).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Mesh file to write (.ply).")],
    resolution: Resolution = 0.05,
    bounds: Bounds = None,
    level: Level = 0.5,
    max_gib: MaxGiB = 1.0,
) -> None:
    """Surface mesh of a 3D map by marching cubes, as binary PLY coloured by height."""
    from ehm.io.ply import write_ply_mesh
    from ehm.viz.colors import vertex_colors

    hilbert_map = _load_or_fail(map_path)
    if hilbert_map.dim != 3:
        raise typer.BadParameter(
            "a 2D map has no surface mesh: 'ehm render' draws it as a PNG and 'ehm grid' "
            "saves its grid"
        )
    occupancy_grid = _grid_or_fail(hilbert_map, bounds, resolution, max_gib)
    try:
        vertices, faces = occupancy_grid.mesh(level)
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error
    write_ply_mesh(output, vertices, faces, vertex_colors(vertices))
    console.print(f"{len(vertices)} vertices, {len(faces)} faces\nwrote {output}")


@app.command()
def render(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Picture to write (.png).")],
    resolution: Resolution = 0.05,
    bounds: Bounds = None,
    level: Level = 0.5,
    cut_above: Annotated[
        float | None, typer.Option(help="Leave out the mesh above this height, metres.")
    ] = None,
    azimuth: Annotated[float, typer.Option(help="View direction, degrees from +x.")] = -60.0,
    elevation: Annotated[float, typer.Option(help="View angle above the horizon.")] = 45.0,
    slices: Annotated[
        Path | None, typer.Option(help="Also write horizontal occupancy slices to this PNG.")
    ] = None,
    std: Annotated[
        Path | None,
        typer.Option(
            help="Also write the occupancy's standard deviation to this PNG: horizontal "
            "slices (3D) or the plane (2D)."
        ),
    ] = None,
    max_gib: MaxGiB = 1.0,
) -> None:
    """Picture of a map, off-screen: its mesh coloured by height (3D) or its grid (2D)."""
    from ehm.viz.pictures import grid_picture, mesh_picture, occupancy_slices
    from ehm.viz.render import Camera

    hilbert_map = _load_or_fail(map_path)
    occupancy_grid = _grid_or_fail(hilbert_map, bounds, resolution, max_gib)
    try:
        if occupancy_grid.dim == 2:
            grid_picture(occupancy_grid, output, title=map_path.name)
        else:
            vertices, faces = occupancy_grid.mesh(level)
            camera = Camera(azimuth=azimuth, elevation=elevation)
            mesh_picture(vertices, faces, output, camera, cut_above, title=map_path.name)
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error
    written = [output]
    low, high = occupancy_grid.bounds
    if slices is not None:
        occupancy_slices(hilbert_map, low, high, slices)
        written.append(slices)
    if std is not None:
        occupancy_slices(hilbert_map, low, high, std, std=True)
        written.append(std)
    console.print("wrote " + " and ".join(str(p) for p in written))


@app.command()
def info(map_path: Annotated[Path, typer.Argument(help="Map file.")]) -> None:
    """What a map file holds."""
    hilbert_map = _load_or_fail(map_path)
    table = Table(title=str(map_path))
    table.add_column("property")
    table.add_column("value")
    table.add_row("dimensions", str(hilbert_map.dim))
    table.add_row("clusters", str(hilbert_map.n_clusters))
    table.add_row("scans", str(hilbert_map.n_scans_))
    table.add_row("memory", f"{hilbert_map.memory_bytes() / 1e6:.3f} MB")
    samples = hilbert_map.memory_
    table.add_row("past samples kept", f"{len(samples)} in {samples.n_cells} cells")
    table.add_row("file size", f"{map_path.stat().st_size / 1e6:.3f} MB")
    low = hilbert_map.clusters_.means.min(axis=0)
    high = hilbert_map.clusters_.means.max(axis=0)
    table.add_row("cluster extent (m)", f"{low.round(2).tolist()} .. {high.round(2).tolist()}")
    for name, value in hilbert_map.config.to_dict().items():
        table.add_row(f"config.{name}", repr(value))
    console.print(table)


def _names(text: str, known: list[str], what: str) -> list[str]:
    """Comma-separated names; 'all' stands for every known one."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return list(known)
    if not names:
        raise typer.BadParameter(f"no {what} given")
    return names


def _numbers(text: str, kind: type, what: str) -> list:
    """Comma-separated finite numbers of `kind`, or a usage error naming `what` and the text."""
    try:
        values = [kind(v) for v in text.split(",") if v.strip()]
    except ValueError as error:
        raise typer.BadParameter(f"{what}: {error}") from error
    if not all(math.isfinite(v) for v in values):
        raise typer.BadParameter(f"{what}: expected finite numbers, got {text!r}")
    return values


@app.command("eval")
def eval_command(
    methods: Annotated[
        str,
        typer.Option(
            help="Comma-separated: octomap hm (= hm-fourier hm-nystrom hm-grid) "
            "lls-hm gpom ehm ehm-alone ehm-batch, or all."
        ),
    ] = "all",
    datasets: Annotated[
        str,
        typer.Option(
            help="Comma-separated: virtual_room warehouse street octomap_scan "
            "tum_fr2_pioneer_slam2 pcl_room intel_lab, or all."
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

    if data_dir is not None:
        os.environ["EHM_DATA_DIR"] = str(data_dir)
    try:
        fraction_list = _numbers(fractions, float, "fractions")
        seed_list = _numbers(seeds, int, "seeds")
        plan = plan_evaluation(
            _names(methods, list(METHODS), "methods"),
            _names(datasets, list(DATASETS), "data sets"),
            fraction_list,
            resolution,
            skip_missing=True,
        )
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error
    for message in plan.skipped:
        console.print(f"[yellow]{message}[/yellow]")
    if not plan.methods or not plan.datasets:
        console.print("[red]error:[/red] nothing to evaluate")
        raise typer.Exit(1)

    records = []
    runs = len(plan.datasets) * len(fraction_list) * len(seed_list) * len(plan.methods)
    with _progress() as progress:
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
