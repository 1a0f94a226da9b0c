"""The `ehm` command: demo, map, query, grid, mesh, render, info, eval. Heavy imports happen inside
each command so that `ehm --help` is instant."""

from __future__ import annotations

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
            overrides[name] = value.lower() in ("1", "true", "yes", "on")
        else:
            overrides[name] = kind(value)
    return overrides


def _load_or_fail(path: Path):
    """The map at `path`, or a one-line error and exit status 1."""
    from ehm.io.map_file import MapFileError, load

    try:
        return load(path)
    except (MapFileError, FileNotFoundError) as error:
        console.print(f"[red]error:[/red] {error}")
        raise typer.Exit(1) from error


def _grid_or_fail(hilbert_map, bounds: str | None, resolution: float, max_gib: float):
    """The map's grid over `bounds` ('x0,y0,..' text), or a usage error naming the problem."""
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
        return hilbert_map.grid(box, resolution, max_bytes=int(max_gib * 2**30))
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
    import numpy as np

    from ehm.datasets import virtual_room
    from ehm.evaluation import exact_test_points, score
    from ehm.io.mesh_file import write_ply_mesh
    from ehm.model import HilbertMap
    from ehm.plots import mesh_picture, occupancy_slices
    from ehm.render import Camera
    from ehm.timing import StageTimer

    out.mkdir(parents=True, exist_ok=True)
    timer = StageTimer()
    with timer("simulate LiDAR"):
        data = virtual_room(seed=seed)
    hilbert_map = HilbertMap(seed=seed)
    with _progress() as progress:
        task = progress.add_task("mapping", total=len(data.scans))
        for scan in data.scans:
            hilbert_map.integrate_scan(scan)
            progress.advance(task)
    stages = dict(hilbert_map.timings_)

    rng = np.random.default_rng(seed + 1)
    low, high = data.scene.box_min.min(axis=0), data.scene.box_max.max(axis=0)
    near, uniform = exact_test_points(
        data.scans, low, high, 0.5, 200_000, hilbert_map.config.surface_margin, rng
    )
    table = Table(title="Accuracy against the exact occupancy of the virtual room")
    for column in ("test points", "n", "occupied", "accuracy", "F1", "ROC-AUC"):
        table.add_column(column, justify="right" if column != "test points" else "left")
    for name, points in (("near surfaces", near), ("uniform, observed region", uniform)):
        with timer(f"query {name}"):
            probability = hilbert_map.occupancy(points)
        labels = data.scene.occupied(points)
        s = score(labels, probability)
        table.add_row(
            name,
            f"{len(points)}",
            f"{labels.mean():.1%}",
            f"{s.accuracy:.3f}",
            f"{s.f1:.3f}",
            f"{s.auc:.3f}",
        )
    map_path = out / "virtual_room.ehm"
    with timer("save map"):
        hilbert_map.save(map_path)
    slices_path = out / "virtual_room_slices.png"
    with timer("draw slices"):
        occupancy_slices(hilbert_map, low, high, slices_path, data.scene, (0.3, 0.75, 1.2, 2.0))
    with timer("grid (0.05 m)"):
        occupancy_grid = hilbert_map.grid(resolution=0.05)
    with timer("mesh"):
        vertices, faces = occupancy_grid.mesh()
    mesh_path, picture_path = out / "virtual_room.ply", out / "virtual_room_mesh.png"
    with timer("save mesh"):
        write_ply_mesh(mesh_path, vertices, faces, _height_colors(vertices))
    with timer("render mesh"):
        camera = Camera(azimuth=-60.0, elevation=55.0)
        title = "virtual room, mesh at p = 0.5 cut at 2.2 m"
        mesh_picture(vertices, faces, picture_path, camera, cut_above=2.2, title=title)

    console.print(table)
    console.print(_timings_table("Integrate, per stage (Table 2)", stages))
    console.print(_timings_table("Demo, per step", timer.seconds))
    console.print(
        f"{hilbert_map!r}: {hilbert_map.memory_bytes() / 1e6:.2f} MB from "
        f"{len(data.scans[0])} rays; {occupancy_grid!r}; mesh of {len(faces)} faces"
    )
    for path in (map_path, slices_path, mesh_path, picture_path):
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
    setting: Annotated[
        list[str] | None, typer.Option("--set", help="MapConfig override name=value.")
    ] = None,
) -> None:
    """Build a map from scans of any supported format and save it."""
    from ehm.io.readers import read_scans
    from ehm.model import HilbertMap
    from ehm.timing import StageTimer

    timer = StageTimer()
    sensor = [float(v) for v in origin.split(",")] if origin else None
    try:
        with timer("read"):
            scans = read_scans(inputs, format=format, origin=sensor, poses=poses)
        hilbert_map = HilbertMap(**_parse_settings(setting or []))
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error
    stages: dict[str, float] = {}
    with timer("map"), _progress() as progress:
        task = progress.add_task("mapping", total=len(scans))
        if batch:
            hilbert_map.fit(scans)
            progress.advance(task, len(scans))
            stages = dict(hilbert_map.timings_)
        else:
            for scan in scans:
                hilbert_map.integrate_scan(scan)
                for stage, value in hilbert_map.timings_.items():
                    stages[stage] = stages.get(stage, 0.0) + value
                progress.advance(task)
    with timer("save"):
        hilbert_map.save(output)
    console.print(_timings_table("Integrate, per stage", stages))
    n_rays = sum(len(s) for s in scans)
    dropped = sum(s.n_dropped for s in scans)
    console.print(
        f"{len(scans)} scans, {n_rays} rays ({dropped} non-finite dropped) -> {hilbert_map!r}, "
        f"{hilbert_map.memory_bytes() / 1e6:.2f} MB; wrote {output} in {timer.total:.1f} s"
    )


@app.command()
def query(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    points: Annotated[Path, typer.Argument(help="Points: .npy (n, d) or .csv with d columns.")],
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write .npy or .csv; default stdout.")
    ] = None,
    mode: Annotated[str | None, typer.Option(help="batch or exact.")] = None,
) -> None:
    """Occupancy probability of each point."""
    import numpy as np

    hilbert_map = _load_or_fail(map_path)
    if points.suffix == ".npy":
        query_points = np.load(points)
    else:
        query_points = np.loadtxt(points, delimiter=",", ndmin=2, comments="#")
    try:
        probability = hilbert_map.occupancy(query_points, mode=mode)
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error
    if output is None:
        typer.echo("\n".join(f"{p:.6f}" for p in probability))
    elif output.suffix == ".npy":
        np.save(output, probability)
    else:
        np.savetxt(output, probability, fmt="%.6f")


@app.command()
def grid(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Grid file to write (.npz).")],
    resolution: Resolution = 0.05,
    bounds: Bounds = None,
    max_gib: MaxGiB = 1.0,
) -> None:
    """Occupancy grid of a map (incremental grid reconstruction), saved as .npz with arrays
    probability, scores, origin, resolution and intercept."""
    from ehm.grid import save_grid

    hilbert_map = _load_or_fail(map_path)
    occupancy_grid = _grid_or_fail(hilbert_map, bounds, resolution, max_gib)
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
    from ehm.io.mesh_file import write_ply_mesh

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
    write_ply_mesh(output, vertices, faces, _height_colors(vertices))
    console.print(f"{len(vertices)} vertices, {len(faces)} faces\nwrote {output}")


def _height_colors(vertices):
    """(V, 3) uint8 RGB of each vertex's height on the colour map of rendered pictures."""
    import numpy as np

    from ehm.render import height_colors

    if len(vertices) == 0:
        return np.zeros((0, 3), dtype=np.uint8)
    z = vertices[:, 2]
    return np.round(255 * height_colors(z, (z.min(), z.max()))).astype(np.uint8)


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
    max_gib: MaxGiB = 1.0,
) -> None:
    """Picture of a map, off-screen: its mesh coloured by height (3D) or its grid (2D)."""
    from ehm.plots import grid_picture, mesh_picture, occupancy_slices
    from ehm.render import Camera

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
    if slices is not None:
        low, high = occupancy_grid.bounds
        occupancy_slices(hilbert_map, low, high, slices)
        written.append(slices)
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
    try:
        return [kind(v) for v in text.split(",") if v.strip()]
    except ValueError as error:
        raise typer.BadParameter(f"{what}: {error}") from error


def _summary_table(dataset: str, summaries) -> Table:
    from rich import box

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


@app.command("eval")
def eval_command(
    methods: Annotated[
        str,
        typer.Option(
            help="Comma-separated: octomap hm (= hm-fourier hm-nystrom hm-grid) "
            "lls-hm gpom ehm ehm-batch, or all."
        ),
    ] = "all",
    datasets: Annotated[
        str,
        typer.Option(
            help="Comma-separated: virtual_room octomap_scan tum_fr2_pioneer_slam2 "
            "pcl_room intel_lab, or all."
        ),
    ] = "virtual_room",
    fractions: Annotated[str, typer.Option(help="Train fractions of the rays.")] = "0.8,0.6,0.4",
    seeds: Annotated[str, typer.Option(help="Comma-separated seeds of the splits.")] = "0",
    resolution: Annotated[
        float, typer.Option(help="Voxel side of OctoMap and of the test split's margin, metres.")
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

    from ehm.baselines import METHODS, make_mapper
    from ehm.comparison import check_request, evaluate_scans, summarise
    from ehm.datasets import DATASETS, DataMissingError, load_dataset

    if data_dir is not None:
        os.environ["EHM_DATA_DIR"] = str(data_dir)
    try:
        dataset_list = _names(datasets, list(DATASETS), "data sets")
        fraction_list = _numbers(fractions, float, "fractions")
        seed_list = _numbers(seeds, int, "seeds")
        method_list = check_request(
            _names(methods, list(METHODS), "methods"), dataset_list, fraction_list
        )
    except ValueError as error:
        raise typer.BadParameter(str(error)) from error

    descriptions = {}
    for method in list(method_list):
        try:
            descriptions[method] = make_mapper(method, resolution, 0).description
        except ImportError as error:
            console.print(f"[yellow]skipped {method}:[/yellow] {error}")
            method_list.remove(method)
    loaded = {}
    for dataset in dataset_list:
        try:
            loaded[dataset] = load_dataset(dataset)
        except DataMissingError as error:
            console.print(f"[yellow]skipped {dataset}:[/yellow] {error}")
    if not method_list or not loaded:
        console.print("[red]error:[/red] nothing to evaluate")
        raise typer.Exit(1)

    records = []
    runs = len(loaded) * len(fraction_list) * len(seed_list) * len(method_list)
    with _progress() as progress:
        task = progress.add_task("evaluating", total=runs)
        for dataset, scans in loaded.items():
            for record in evaluate_scans(
                dataset, scans, method_list, fraction_list, seed_list, resolution
            ):
                records.append(record)
                progress.update(
                    task,
                    advance=1,
                    description=f"{dataset} {record.fraction:.0%} seed {record.seed}: "
                    f"{record.method}",
                )

    summaries = summarise(records)
    for dataset in loaded:
        table = _summary_table(dataset, [s for s in summaries if s.dataset == dataset])
        # Piped or logged output is 80 columns by default: too narrow for the table.
        (console if console.is_terminal else Console(width=140)).print(table)
    for method, description in descriptions.items():
        if method in method_list:
            console.print(f"[bold]{method}[/bold]: {description}")
    if json_path is not None:
        json_path.write_text(json.dumps([r.to_dict() for r in records], indent=1) + "\n")
        console.print(f"wrote {json_path} ({len(records)} records)")
    if plots is not None:
        from ehm.comparison_plots import write_comparison_plots

        for path in write_comparison_plots(summaries, plots):
            console.print(f"wrote {path}")
