"""The `ehm` command: demo, map, query, grid, mesh, render, export, info, eval. Heavy imports happen
inside each command so that `ehm --help` is instant.

A mistake in the input (ehm.EhmError: a file that cannot be read, a bad setting or option, an
output that may not be written) ends in one line, `error: ...`, on stderr and exit status 2,
before any work where it can be checked first. Anything else is a bug: one line and exit
status 1, or its traceback with `ehm --debug`."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from typer.core import TyperGroup

from ehm.errors import EhmError, EmptyMapError, InputError


class _Commands(TyperGroup):
    """The command group: turns ehm's errors into one line on stderr (see the module)."""

    def invoke(self, ctx: Any) -> Any:
        try:
            return super().invoke(ctx)
        except (EhmError, ImportError) as error:
            # An ImportError is a mistake only where an optional part is missing (its message
            # names the extra to install); any other is a bug.
            optional = isinstance(error, ImportError) and "pip install 'ehm[" in str(error)
            if ctx.params.get("debug") or not (isinstance(error, EhmError) or optional):
                raise
            errors.print(f"[red]error:[/red] {escape(str(error))}")
            raise typer.Exit(2) from None
        except Exception as error:
            # Exceptions that carry an exit status are typer's own ways out; a closed pipe
            # (`ehm query ... | head`) typer ends quietly.
            if (
                ctx.params.get("debug")
                or hasattr(error, "exit_code")
                or isinstance(error, typer.Abort | BrokenPipeError)
            ):
                raise
            errors.print(
                f"[red]error:[/red] {escape(type(error).__name__)}: {escape(str(error))}\n"
                "This is a bug in ehm; `ehm --debug ...` shows where it happened."
            )
            raise typer.Exit(1) from None


app = typer.Typer(
    cls=_Commands,
    help="Efficient Hilbert Maps: continuous occupancy maps from range scans.",
    no_args_is_help=True,
    rich_markup_mode="rich",
)
console = Console()
errors = Console(stderr=True, soft_wrap=True)  # one line an error, however long


@app.callback()
def _options(
    debug: Annotated[
        bool, typer.Option("--debug", help="Show the Python traceback of any error.")
    ] = False,
) -> None:
    """Efficient Hilbert Maps: continuous occupancy maps from range scans."""


Resolution = Annotated[float, typer.Option(help="Voxel side of the grid, metres.")]
Bounds = Annotated[
    str | None,
    typer.Option(
        help="Grid box 'x0,y0,z0,x1,y1,z1' (2D: 'x0,y0,x1,y1'), metres; default: all of the map."
    ),
]
MaxGiB = Annotated[float, typer.Option(help="Refuse grids larger than this, GiB.")]
Level = Annotated[float, typer.Option(help="Occupancy probability of the surface.")]
Force = Annotated[bool, typer.Option("--force", help="Overwrite output files that exist.")]


def _parse_settings(settings: list[str]) -> dict:
    """`name=value` pairs into MapConfig overrides, values typed like the defaults."""
    from ehm.config import MapConfig

    defaults = MapConfig().to_dict()
    overrides = {}
    for item in settings:
        name, sep, value = item.partition("=")
        if not sep or name not in defaults:
            raise InputError(f"--set {item!r}: expected name=value with a MapConfig name")
        kind = type(defaults[name])
        if kind is bool:
            words = {"1": True, "true": True, "yes": True, "on": True}
            words |= {"0": False, "false": False, "no": False, "off": False}
            if value.lower() not in words:
                raise InputError(f"--set {item!r}: {name} is true or false, got {value!r}")
            overrides[name] = words[value.lower()]
        else:
            try:
                overrides[name] = kind(value)
            except ValueError as error:
                raise InputError(
                    f"--set {item!r}: {name} is a{'n' if kind is int else ''} {kind.__name__}, "
                    f"got {value!r}"
                ) from error
    return overrides


def _load(path: Path):
    """The map at `path`, a file or a tiled map's directory (ehm.load)."""
    from ehm.maps import load

    return load(path)


def _box(hilbert_map, bounds: str | None):
    """(2, d) float64 bounds from 'x0,y0,..' text, or None."""
    import numpy as np

    if bounds is None:
        return None
    box = np.array(_numbers(bounds, float, "--bounds"))
    if len(box) != 2 * hilbert_map.dim:
        raise InputError(
            f"--bounds: {2 * hilbert_map.dim} numbers for a {hilbert_map.dim}D map, got {len(box)}"
        )
    return box.reshape(2, hilbert_map.dim)


def _grid(hilbert_map, box, resolution: float, max_gib: float, std: bool = False):
    """The map's grid over `box` ((2, d) or None: all of the map), with the std when asked."""
    if not 0 < max_gib < math.inf:
        raise InputError(f"--max-gib must be a positive number, got {max_gib}")
    return hilbert_map.grid(box, resolution, max_bytes=int(max_gib * 2**30), std=std)


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


# Kernels ready after this many seconds or more were compiled, not loaded from the cache.
COMPILED_SECONDS = 10.0


def _prepare_kernels() -> None:
    """Compile the map's kernels (the first run after install: about a minute) or load them
    from Numba's cache (a second or two), on a tiny scan, saying which, so that the timings
    shown next are the algorithm's."""
    from ehm.eval.runner import warm_up

    start = time.perf_counter()
    with console.status("preparing the compiled kernels (a minute on the first run after install)"):
        warm_up("ehm", 3)
    seconds = time.perf_counter() - start
    if seconds >= COMPILED_SECONDS:
        console.print(
            f"compiled the kernels in {seconds:.0f} s, once: later runs load them from the cache"
        )
    else:
        console.print(f"loaded the compiled kernels in {seconds:.1f} s")


@app.command()
def demo(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Folder for the map and pictures.")
    ] = Path("ehm_demo"),
    seed: Annotated[int, typer.Option(help="Seed of the simulation and the map.")] = 0,
) -> None:
    """Simulate the virtual room, map it, score the map against the exact occupancy, and write
    the map, occupancy slices, a mesh (PLY) and a picture of the mesh (over the demo's own
    files from an earlier run)."""
    from ehm.eval.demo import run_demo
    from ehm.io.outputs import check_output_folder
    from ehm.pipeline import ProgressBar

    out = check_output_folder(out)
    _prepare_kernels()
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
    inputs: Annotated[
        list[Path], typer.Argument(help="Scan files, a TUM folder, ROS bags (.bag or folders).")
    ],
    output: Annotated[Path, typer.Option("--output", "-o", help="Map file to write.")],
    format: Annotated[
        str | None,
        typer.Option("--format", "-f", help="Reader: xyz ply pcd las kitti graph tum carmen bag."),
    ] = None,
    origin: Annotated[
        str | None,
        typer.Option(
            help="Sensor origin 'x,y,z', world frame, for point clouds (xyz ply pcd las)."
        ),
    ] = None,
    poses: Annotated[
        Path | None,
        typer.Option(
            help="Poses file: for KITTI .bin scans the sequence's (line i places frame i); for "
            "point clouds one T_world_sensor per file in the order given, for bags one per "
            "message (KITTI's 12 numbers or TUM's 'time tx ty tz qx qy qz qw' per line)."
        ),
    ] = None,
    calib: Annotated[
        str | None,
        typer.Option(
            help="KITTI calib.txt (its Tr places the Velodyne in the camera poses); default "
            "the sequence's; 'identity' for poses of the Velodyne itself."
        ),
    ] = None,
    topic: Annotated[
        str | None,
        typer.Option(help="Bags: the PointCloud2 or LaserScan topic (default: the only one)."),
    ] = None,
    frame: Annotated[
        str | None, typer.Option(help="Bags: the fixed frame /tf places the scans in.")
    ] = None,
    odometry: Annotated[
        str | None,
        typer.Option(help="Bags: a nav_msgs/Odometry topic to place the scans by instead."),
    ] = None,
    min_range: Annotated[
        float | None, typer.Option(help="Leave out rays shorter than this, metres.")
    ] = None,
    max_range: Annotated[
        float | None,
        typer.Option(help="Cut rays longer than this, metres: free up to it, no hit there."),
    ] = None,
    every: Annotated[int, typer.Option(help="Take every Nth scan.")] = 1,
    limit: Annotated[
        int | None, typer.Option(help="Stop after this many scans (after --every).")
    ] = None,
    batch: Annotated[bool, typer.Option(help="Learn all scans at once (single batch).")] = False,
    resolution: Annotated[
        float | None,
        typer.Option(
            help="Map detail, metres: scales every length setting (MapConfig.for_resolution); "
            "about 0.2 for long-range outdoor LiDAR.  [default: 0.05]"
        ),
    ] = None,
    setting: Annotated[
        list[str] | None, typer.Option("--set", help="MapConfig override name=value.")
    ] = None,
    force: Force = False,
    quiet: Annotated[
        bool, typer.Option("--quiet", "-q", help="No progress bar, no summary: only errors.")
    ] = False,
    view: Annotated[
        bool,
        typer.Option(
            "--view",
            help="Show the map growing in the browser (pip install 'ehm[viewer]'), and keep "
            "showing it after, until Ctrl-C.",
        ),
    ] = False,
    port: Annotated[int, typer.Option(help="Port of the --view page.")] = 8080,
    tiles: Annotated[
        float | None,
        typer.Option(
            help="Cut the map into tiles this many metres a side, learned in parallel on Dask "
            "(pip install 'ehm[tiles]'); -o names the map's folder."
        ),
    ] = None,
    overlap: Annotated[
        float | None,
        typer.Option(help="With --tiles: how far each tile learns past its border, metres."),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(help="With --tiles: processes of the local cluster (default: cores)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="With --tiles: a Dask scheduler to run on, 'tcp://host:8786'; its workers "
            "must be able to read the inputs."
        ),
    ] = None,
    update: Annotated[
        bool,
        typer.Option(
            "--update",
            help="Add the scans to the map at -o, with its own settings (a tiled map learns "
            "again only the tiles they cross).",
        ),
    ] = False,
) -> None:
    """Build a map from scans of any supported format and save it."""
    from ehm.config import MapConfig
    from ehm.hilbert_map import HilbertMap
    from ehm.io.outputs import check_output, check_output_map_directory
    from ehm.io.readers import ScanFiles
    from ehm.pipeline import MappingPipeline, ProgressBar
    from ehm.tiles.tiled_map import TiledMap

    given = [*inputs, *(p for p in (poses, calib) if p is not None)]
    sensor = _numbers(origin, float, "--origin") if origin else None
    files = ScanFiles(inputs, format, sensor, poses, calib, every, limit, topic, frame, odometry)
    ranges = {"min_range": min_range, "max_range": max_range}
    overrides = {k: v for k, v in ranges.items() if v is not None}
    settings = _parse_settings(setting or [])
    tiled = tiles is not None or (update and output.is_dir())
    if not tiled and (overlap, workers, scheduler) != (None, None, None):
        raise InputError("--overlap, --workers and --scheduler are for tiled maps (--tiles)")
    if tiled and (batch or view):
        raise InputError("--batch and --view are for single maps, not tiled ones")
    if update:
        if overrides or settings or resolution is not None or tiles is not None:
            raise InputError(
                "--update adds scans to a map with its own settings: leave out --resolution, "
                "--set, --min-range, --max-range and --tiles"
            )
        if not output.exists():
            raise InputError(f"--update: {output} does not exist; leave out --update to make it")
        if batch:
            raise InputError("--batch learns all scans afresh: it cannot --update a map")
        if not tiled:
            check_output(output, given, force=True)
        existing = _load(output)
    else:
        detail = 0.05 if resolution is None else resolution
        config = MapConfig.for_resolution(detail, **settings, **overrides)
        if tiled:
            check_output_map_directory(output, given, force)
        else:
            check_output(output, given, force)
    if tiled:
        tiled_map = existing if update else TiledMap(tiles, overlap, config)
        _build_tiles(tiled_map, files, output, workers, scheduler, quiet)
        return
    hilbert_map = existing if update else HilbertMap(config)
    scans = iter(files)
    observers = [] if quiet else [ProgressBar(console)]
    live = None
    if view:
        from ehm.viz.viewer import LiveView

        live = LiveView(port=port)
        observers.append(live)
        console.print(f"watch the map grow at {live.url}")
    run = MappingPipeline(scans, hilbert_map, batch, observers).run()
    hilbert_map.save(output)
    if hilbert_map.n_clusters == 0:
        errors.print(
            "[yellow]warning:[/yellow] the map has no clusters: no scan gave enough samples "
            "together, so every point reads 0.5"
        )
    if not quiet:
        console.print(_timings_table("Mapping, per stage", run.stage_seconds))
        console.print(
            f"{run.n_scans} scans, {run.n_rays} rays ({run.n_dropped} non-finite dropped) -> "
            f"{hilbert_map!r}, {hilbert_map.memory_bytes() / 1e6:.2f} MB, mapped in "
            f"{run.seconds:.1f} s; wrote {output}"
        )
    if live is not None:
        _serve_until_stopped(live.server, f"the map at {live.url}")


def _build_tiles(
    tiled_map,
    files,
    output: Path,
    workers: int | None,
    scheduler: str | None,
    quiet: bool,
) -> None:
    """`ehm map --tiles`: learn the scans of `files` into `tiled_map` on Dask, its tiles
    written to the folder `output` as they come, with a progress bar unless `quiet`."""
    from contextlib import nullcontext

    from ehm.tiles.progress import TileProgressBar

    progress = nullcontext(None) if quiet else TileProgressBar(console)
    with progress as observer:
        report = tiled_map.build(files, scheduler, workers, output, observer)
    if not quiet:
        console.print(
            f"{report.n_scans} scans, {report.n_rays} rays -> {len(report.tiles)} tiles learned "
            f"by {report.workers} workers in {report.seconds:.1f} s (binning "
            f"{report.binning_seconds:.1f} s); {tiled_map!r}; wrote {output}"
        )


@app.command()
def query(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    points: Annotated[
        Path, typer.Argument(help="Points: .npy (n, d) or comma-separated text, d numbers a line.")
    ],
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write .npy or .csv; default stdout.")
    ] = None,
    mode: Annotated[str | None, typer.Option(help="batch or exact.")] = None,
    std: Annotated[
        bool, typer.Option("--std", help="Also the standard deviation: columns p, std.")
    ] = False,
    force: Force = False,
) -> None:
    """Occupancy probability of each point (and with --std its standard deviation)."""
    import numpy as np

    from ehm.io.outputs import check_output
    from ehm.io.points import read_points

    if mode not in (None, "batch", "exact"):
        raise InputError(f"--mode must be batch or exact, got {mode!r}")
    if output is not None:
        check_output(output, [map_path, points], force)
    hilbert_map = _load(map_path)
    answers = hilbert_map.occupancy(read_points(points, hilbert_map.dim), mode=mode, return_std=std)
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
    force: Force = False,
) -> None:
    """Occupancy grid of a map (incremental grid reconstruction), saved as .npz with arrays
    probability, scores, origin, resolution and intercept (and with --std, std)."""
    from ehm.io.grid_file import save_grid
    from ehm.io.outputs import check_output

    check_output(output, [map_path], force, suffix=".npz")
    hilbert_map = _load(map_path)
    occupancy_grid = _grid(hilbert_map, _box(hilbert_map, bounds), resolution, max_gib, std)
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
    force: Force = False,
) -> None:
    """Surface mesh of a 3D map by marching cubes, as binary PLY coloured by height."""
    from ehm.io.outputs import check_output
    from ehm.io.ply import write_ply_mesh
    from ehm.viz.colors import vertex_colors

    check_output(output, [map_path], force, suffix=".ply")
    hilbert_map = _load(map_path)
    if hilbert_map.dim != 3:
        raise InputError(
            f"{map_path}: a 2D map has no surface mesh: 'ehm render' draws it as a PNG and "
            "'ehm grid' saves its grid"
        )
    vertices, faces = _grid(hilbert_map, _box(hilbert_map, bounds), resolution, max_gib).mesh(level)
    if len(faces) == 0:
        raise InputError(f"nothing to mesh: the map does not cross {level} in these bounds")
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
    force: Force = False,
) -> None:
    """Picture of a map, off-screen: its mesh coloured by height (3D) or its grid (2D)."""
    from ehm.io.outputs import check_output
    from ehm.viz.pictures import grid_picture, mesh_picture, occupancy_slices
    from ehm.viz.render import Camera

    written = [p for p in (output, slices, std) if p is not None]
    if len(set(written)) < len(written):
        raise InputError("-o, --slices and --std must name different files")
    for path in written:
        check_output(path, [map_path], force, suffix=".png")
    camera = Camera(azimuth=azimuth, elevation=elevation)
    if cut_above is not None and not math.isfinite(cut_above):
        raise InputError(f"--cut-above must be a finite height, got {cut_above}")
    hilbert_map = _load(map_path)
    occupancy_grid = _grid(hilbert_map, _box(hilbert_map, bounds), resolution, max_gib)
    if occupancy_grid.dim == 2:
        grid_picture(occupancy_grid, output, title=map_path.name)
    else:
        vertices, faces = occupancy_grid.mesh(level)
        mesh_picture(vertices, faces, output, camera, cut_above, title=map_path.name)
    low, high = occupancy_grid.bounds
    if slices is not None:
        occupancy_slices(hilbert_map, low, high, slices)
    if std is not None:
        occupancy_slices(hilbert_map, low, high, std, std=True)
    console.print("wrote " + " and ".join(str(p) for p in written))


@app.command()
def export(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    output: Annotated[
        Path,
        typer.Option(
            "--output",
            "-o",
            help="File to write, by its suffix: .ot (OctoMap, log-odds), .bt (OctoMap, "
            "occupied or free), .pgm (+ .yaml, ROS map_server, 2D), .ply or .pcd (occupied "
            "voxel centres).",
        ),
    ],
    resolution: Resolution = 0.05,
    bounds: Bounds = None,
    level: Annotated[
        float, typer.Option(help="Occupancy above which a voxel is occupied (.ply, .pcd).")
    ] = 0.5,
    max_gib: MaxGiB = 1.0,
    force: Force = False,
) -> None:
    """Export a map's grid for robotics tools: OctoMap trees that octovis and octomap_server
    open, map_server maps for nav2, point clouds of the occupied voxels. The bounds widen to
    multiples of the resolution, so the voxels are OctoMap's."""
    import numpy as np

    from ehm.io import exports
    from ehm.io.outputs import check_output

    suffixes = (*exports.OCTOMAP_SUFFIXES, ".pgm", ".ply", ".pcd")
    if output.suffix.lower() not in suffixes:
        raise InputError(f"{output}: expected a name ending in {', '.join(suffixes)}")
    check_output(output, [map_path], force)
    if output.suffix == ".pgm":
        check_output(output.with_suffix(".yaml"), [map_path], force)
    hilbert_map = _load(map_path)
    if not 0.0 < resolution < math.inf:
        raise InputError(f"--resolution must be a positive number of metres, got {resolution}")
    box = _box(hilbert_map, bounds)
    aligned = exports.aligned_bounds(hilbert_map.extent() if box is None else box, resolution)
    occupancy_grid = _grid(hilbert_map, aligned, resolution, max_gib)
    if output.suffix in exports.OCTOMAP_SUFFIXES:
        known = exports.write_octomap(occupancy_grid, output)
        console.print(f"{occupancy_grid!r}: {known} known voxels\nwrote {output}")
    elif output.suffix == ".pgm":
        yaml_path = exports.write_map_server(occupancy_grid, output)
        console.print(f"{occupancy_grid!r}\nwrote {output} and {yaml_path}")
    else:
        points = exports.occupied_voxels(occupancy_grid, level)
        if occupancy_grid.dim == 2:
            points = np.column_stack([points, np.zeros(len(points))])
        exports.write_point_cloud(points, output)
        console.print(f"{len(points)} occupied voxels\nwrote {output}")


def _serve_until_stopped(server, what: str) -> None:
    """Keep a viewer's server running until Ctrl-C."""
    import time

    console.print(f"showing {what} (Ctrl-C stops)")
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        server.stop()


@app.command()
def view(
    map_path: Annotated[Path, typer.Argument(help="Map file.")],
    port: Annotated[int, typer.Option(help="Port of the web page.")] = 8080,
    host: Annotated[
        str, typer.Option(help="Address to serve on (0.0.0.0: every interface).")
    ] = "127.0.0.1",
    resolution: Annotated[float, typer.Option(help="Voxel side of the surface, metres.")] = 0.1,
) -> None:
    """Look at a map in the browser (pip install 'ehm[viewer]'): its surface at an occupancy
    level coloured by height or uncertainty, a slice of the occupancy, the samples it keeps,
    the sensor path. Ctrl-C stops the server."""
    from ehm.viz.viewer import MapViewer, viser_module

    if not 0 < port < 65536:
        raise InputError(f"--port must be 1 to 65535, got {port}")
    viser_module()
    hilbert_map = _load(map_path)
    viewer = MapViewer(hilbert_map, resolution, port, host)
    _serve_until_stopped(viewer.server, f"{map_path} at {viewer.url}")


@app.command()
def info(map_path: Annotated[Path, typer.Argument(help="Map file.")]) -> None:
    """What a map file holds."""
    import numpy as np

    hilbert_map = _load(map_path)
    table = Table(title=str(map_path))
    table.add_column("property")
    table.add_column("value")
    if map_path.is_dir():
        _tiled_map_rows(table, hilbert_map)
        console.print(table)
        return
    table.add_row("dimensions", str(hilbert_map.dim))
    table.add_row("clusters", str(hilbert_map.n_clusters))
    table.add_row("scans", str(hilbert_map.n_scans_))
    path = hilbert_map.sensor_path
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) else 0.0
    table.add_row("sensor path", f"{len(path)} poses, {length:.2f} m long")
    table.add_row("memory", f"{hilbert_map.memory_bytes() / 1e6:.3f} MB")
    memory = hilbert_map.memory_
    table.add_row("past evidence kept", f"{len(memory)} cells, {memory.weight.sum():.0f} samples")
    table.add_row("file size", f"{map_path.stat().st_size / 1e6:.3f} MB")
    means = hilbert_map.clusters_.means
    if len(means):
        low, high = means.min(axis=0).round(2).tolist(), means.max(axis=0).round(2).tolist()
        table.add_row("cluster extent (m)", f"{low} .. {high}")
    else:
        table.add_row("cluster extent (m)", "none: the map is empty, every point reads 0.5")
    for name, value in hilbert_map.config.to_dict().items():
        table.add_row(f"config.{name}", repr(value))
    console.print(table)


def _tiled_map_rows(table: Table, tiled_map) -> None:
    """`ehm info` of a tiled map: read from its index alone, no tile loaded."""
    import numpy as np

    records = [tiled_map.tile_record(key) for key in tiled_map.tile_keys]
    sizes = np.array([record.n_bytes for record in records])
    table.add_row("kind", "tiled map (a folder of tile maps and index.json)")
    table.add_row("dimensions", str(tiled_map.dim))
    table.add_row(
        "tiles",
        f"{len(records)} of {tiled_map.tile_size:g} m, learning {tiled_map.overlap:g} m past "
        "their borders",
    )
    table.add_row("scans", str(tiled_map.n_scans_))
    path = tiled_map.sensor_path
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) else 0.0
    table.add_row("sensor path", f"{len(path)} poses, {length:.2f} m long")
    table.add_row("clusters", f"{sum(record.n_clusters for record in records)} in all tiles")
    table.add_row(
        "tile files",
        f"{sizes.sum() / 1e6:.3f} MB: {sizes.min() / 1e6:.3f} to {sizes.max() / 1e6:.3f} MB "
        f"each, median {np.median(sizes) / 1e6:.3f}",
    )
    versions = [record.version for record in records]
    table.add_row("tile versions", f"{min(versions)} to {max(versions)}")
    try:
        low, high = tiled_map.extent().round(2).tolist()
        table.add_row("cluster extent (m)", f"{low} .. {high}")
    except EmptyMapError:
        table.add_row("cluster extent (m)", "none: the map is empty, every point reads 0.5")
    for name, value in tiled_map.config.to_dict().items():
        table.add_row(f"config.{name}", repr(value))


def _names(text: str, known: list[str], what: str) -> list[str]:
    """Comma-separated names; 'all' stands for every known one."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return list(known)
    if not names:
        raise InputError(f"no {what} given")
    return names


def _numbers(text: str, kind: type, what: str) -> list:
    """Comma-separated finite numbers of `kind`; InputError naming `what` and the text."""
    try:
        values = [kind(v) for v in text.split(",") if v.strip()]
    except ValueError as error:
        raise InputError(f"{what}: {error}") from error
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{what}: expected finite numbers, got {text!r}")
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
    from ehm.io.outputs import check_output, check_output_folder

    if json_path is not None:
        check_output(json_path, force=force, suffix=".json")
    if plots is not None:
        check_output_folder(plots)
    if data_dir is not None:
        os.environ["EHM_DATA_DIR"] = str(data_dir)
    fraction_list = _numbers(fractions, float, "--fractions")
    seed_list = _numbers(seeds, int, "--seeds")
    plan = plan_evaluation(
        _names(methods, list(METHODS), "methods"),
        _names(datasets, list(DATASETS), "data sets"),
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
