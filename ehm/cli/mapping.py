"""`ehm demo` and `ehm map`: maps from simulated scans and from files, one map or tiles."""

from __future__ import annotations

import math
import signal
from collections.abc import Iterator
from operator import length_hint
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ehm.cli.app import (
    Force,
    app,
    cli_log,
    console,
    errors,
    load_map,
    parse_numbers,
    parse_settings,
    serve_until_stopped,
    timings_table,
)
from ehm.errors import InputError

# Kernels ready after this many seconds or more were compiled, not loaded from the cache.
COMPILED_SECONDS = 10.0


def _prepare_kernels() -> None:
    """Compile every kernel (the first run after install: a minute or two) or load them from
    Numba's cache (a few seconds), with the step on a status line, saying which happened."""
    from ehm.warm import warm_kernels

    with console.status("preparing the compiled kernels") as status:
        seconds = warm_kernels(
            lambda step: status.update(f"preparing the compiled kernels: {step}")
        )
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
    data: Annotated[
        Path | None,
        typer.Option(
            help="Instead, write the small recordings the guides use into this folder "
            "(floor.log, room.bag, tum_fr2/, kitti/), and stop.",
        ),
    ] = None,
) -> None:
    """Simulate the virtual room, map it, score the map against the exact occupancy, and write
    the map, occupancy slices, a mesh (PLY) and a picture of the mesh (over the demo's own
    files from an earlier run). With --data, write the guides' recordings instead."""
    from ehm.eval.demo import run_demo
    from ehm.io.output_paths import check_output_folder
    from ehm.pipeline import ProgressBar

    if data is not None:
        from ehm.eval.guide_files import write_guide_files

        write_guide_files(check_output_folder(data), console.print)
        return
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
    console.print(timings_table("Integrate, per stage (Table 2)", result.run.stage_seconds))
    console.print(timings_table("Demo, per step", result.steps))
    console.print(
        f"{hilbert_map!r}: {hilbert_map.memory_bytes() / 1e6:.2f} MB from "
        f"{result.run.n_rays} rays; {result.grid!r}; mesh of {result.n_faces} faces"
    )
    for path in result.written:
        console.print(f"wrote {path}")


@app.command()
def warm() -> None:
    """Compile every kernel of learning, queries and outputs now, in 2D and 3D (a minute or
    two, once after install; `ehm demo` does it too), so that no later command or first query
    waits on compiling."""
    _prepare_kernels()


@app.command("map")
def map_command(
    inputs: Annotated[
        list[Path],
        typer.Argument(
            metavar="INPUTS...",
            help="Scan files, depth folders (TUM, 7-Scenes, Redwood), KITTI sequences, LiDAR "
            "captures (.pcap), ROS bags (.bag, or ROS 2 bag folders).",
        ),
    ],
    output: Annotated[Path, typer.Option("--output", "-o", help="Map file to write.")],
    format: Annotated[
        str | None,
        typer.Option(
            "--format",
            "-f",
            help="Reader (default: by the input's name and content): xyz ply pcd las kitti "
            "graph tum 7scenes redwood carmen bag ouster velodyne.",
        ),
    ] = None,
    origin: Annotated[
        str | None,
        typer.Option(
            help="Sensor origin 'x,y,z', world frame: for point clouds (xyz ply pcd las), and "
            "where a sensor that stood still stands (KITTI .bin without poses, LiDAR captures, "
            "bags without /tf)."
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
    intrinsics: Annotated[
        str | None,
        typer.Option(
            help="Depth frames and depth images in bags: the camera 'fx,fy,cx,cy', pixels "
            "(default: the layout's own, TUM's by the sequence's name; a bag's CameraInfo)."
        ),
    ] = None,
    depth_scale: Annotated[
        float | None,
        typer.Option(
            help="Depth frames and depth images in bags: raw depth units a metre, 1000 for "
            "millimetres (default: the layout's own, TUM 5000; a bag image's encoding)."
        ),
    ] = None,
    fov: Annotated[
        float | None,
        typer.Option(
            help="CARMEN FLASER lines: the laser's field of view, degrees (ROBOTLASER1 lines "
            "carry theirs).  \\[default: 180]"
        ),
    ] = None,
    topic: Annotated[
        str | None,
        typer.Option(
            help="Bags: the PointCloud2, LaserScan, VelodyneScan or depth Image topic (default: "
            "the only one)."
        ),
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
            "about 0.2 for long-range outdoor LiDAR.  \\[default: 0.05]"
        ),
    ] = None,
    profile: Annotated[
        str | None,
        typer.Option(
            help="'realtime' learns faster, with wider clusters and one epoch, a little less "
            "precisely near surfaces (MapConfig.for_resolution); 'default' is the most "
            "accurate.  \\[default: default]"
        ),
    ] = None,
    config_file: Annotated[
        Path | None,
        typer.Option(
            "--config",
            help="Settings file (TOML: resolution, then a table per section of MapConfig, as "
            "the .settings.toml written beside every map); --resolution and --set override it.",
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
            help="Show the map growing in the browser (pip install 'ehm\\[viewer]'), and keep "
            "showing it after, until Ctrl-C.",
        ),
    ] = False,
    port: Annotated[int, typer.Option(help="Port of the --view page.")] = 8080,
    tiles: Annotated[
        float | None,
        typer.Option(
            help="Cut the map into tiles this many metres a side, learned in parallel on Dask "
            "(pip install 'ehm\\[tiles]'); -o names the map's folder."
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
    """Build a map from scans of any supported format and save it, with the settings it was
    made with beside it (map.settings.toml; `--config` reads such a file)."""
    from ehm.io.output_paths import check_output
    from ehm.io.readers import ScanFiles

    given = [*inputs, *(p for p in (poses, calib) if p is not None)]
    sensor = parse_numbers(origin, float, "--origin") if origin else None
    camera = parse_numbers(intrinsics, float, "--intrinsics") if intrinsics else None
    files = ScanFiles(
        inputs, format, origin=sensor, poses=poses, calib=calib, intrinsics=camera,
        depth_scale=depth_scale, fov=None if fov is None else math.radians(fov),
        every=every, limit=limit, topic=topic, frame=frame, odometry=odometry,
    )  # fmt: skip
    ranges = {"min_range": min_range, "max_range": max_range}
    overrides = {k: v for k, v in ranges.items() if v is not None}
    settings = parse_settings(setting or [])
    tiled = tiles is not None or (update and output.is_dir())
    if not tiled and (overlap, workers, scheduler) != (None, None, None):
        raise InputError("--overlap, --workers and --scheduler are for tiled maps (--tiles)")
    if tiled and (batch or view):
        raise InputError("--batch and --view are for single maps, not tiled ones")
    if update:
        asked = (overrides, settings, resolution, profile, tiles, config_file)
        if any(item for item in asked if item is not None):
            raise InputError(
                "--update adds scans to a map with its own settings: leave out --resolution, "
                "--profile, --config, --set, --min-range, --max-range and --tiles"
            )
        target = _map_to_update(output, given, tiled, batch)
    else:
        config = _settings(config_file, resolution, profile).replace(**settings, **overrides)
        target = _new_map(output, given, force, config, tiles if tiled else None, overlap)
        if not tiled:  # a tiled map's folder is its own
            check_output(settings_path(output, tiled), given, force)
    if tiled:
        _build_tiles(target, files, output, workers, scheduler, quiet)
    else:
        _learn_scans(target, files, output, batch, quiet, port if view else None)


def _settings(config_file: Path | None, resolution: float | None, profile: str | None):
    """The settings of a new map: the file's (its resolution replaced by `resolution` when
    given), else the `profile`'s at `resolution` (0.05 m when None)."""
    from ehm.config import DEFAULT_RESOLUTION, MapConfig
    from ehm.io.files import read_input

    if config_file is None:
        resolution = DEFAULT_RESOLUTION if resolution is None else resolution
        return MapConfig.for_resolution(resolution, profile or "default")
    if profile is not None:
        raise InputError("a settings file holds every setting of its profile: leave out --profile")
    text = read_input(config_file).decode("utf-8", errors="replace")
    return MapConfig.from_toml(text, str(config_file), resolution)


def settings_path(output: Path, tiled: bool) -> Path:
    """Where the settings a map was made with are written: beside a map file (map.ehm:
    map.settings.toml), inside a tiled map's folder (settings.toml)."""
    return output / "settings.toml" if tiled else output.with_suffix(".settings.toml")


def _map_to_update(output: Path, given: list[Path], tiled: bool, batch: bool):
    """`ehm map --update`: the map at `output`, once it is known that it can take scans."""
    from ehm.io.output_paths import check_output

    if not output.exists():
        raise InputError(f"--update: {output} does not exist; leave out --update to make it")
    if batch:
        raise InputError("--batch learns all scans afresh: it cannot --update a map")
    if not tiled:
        check_output(output, given, force=True)
    return load_map(output)


def _new_map(
    output: Path,
    given: list[Path],
    force: bool,
    config,
    tiles: float | None,
    overlap: float | None,
):
    """A new map of `config` to write at `output`: a TiledMap of `tiles` metres a side
    learning `overlap` past their borders, or with tiles None a HilbertMap."""
    from ehm.io.output_paths import check_output, check_output_map_directory

    if tiles is not None:
        from ehm.tiles.tiled_map import TiledMap

        check_output_map_directory(output, given, force)
        return TiledMap(tiles, overlap, config)
    from ehm.hilbert_map import HilbertMap

    check_output(output, given, force)
    return HilbertMap(config)


def _learn_scans(hilbert_map, files, output: Path, batch: bool, quiet: bool, port: int | None):
    """Learn the scans of `files` into `hilbert_map` and save it at `output`, with a progress
    bar and a summary unless `quiet`; with a `port`, showing it live in the browser there and
    after, until Ctrl-C."""
    from ehm.io.files import write_atomically
    from ehm.pipeline import MappingPipeline, ProgressBar

    observers = [] if quiet else [ProgressBar(console)]
    live = None
    if port is not None:
        from ehm.viz.viewer import LiveView

        live = LiveView(port=port)
        observers.append(live)
        console.print(f"watch the map grow at {live.url}")
    with FirstInterrupt() as interrupt:
        scans = interrupt.until_asked(iter(files))
        total = length_hint(files, -1)  # the wrapper below hides the files' own hint
        run = MappingPipeline(
            scans, hilbert_map, batch, observers, None if total < 0 else total
        ).run()
        hilbert_map.save(output)
        write_atomically(settings_path(output, False), hilbert_map.config.to_toml().encode())
    if interrupt.asked:
        stopped = f"stopped by Ctrl-C after {run.n_scans} scans; the map of those is saved:"
        stopped += f" {output}"
        errors.print(stopped)
        cli_log.warning(stopped)
        raise typer.Exit(130)
    if hilbert_map.n_clusters == 0:
        errors.print(
            "[yellow]warning:[/yellow] the map has no clusters: no scan gave enough samples "
            "together, so every point reads 0.5"
        )
    else:
        _hint_resolution(hilbert_map)
    if not quiet:
        console.print(timings_table("Mapping, per stage", run.stage_seconds))
        console.print(
            f"{run.n_scans} scans, {run.n_rays} rays ({run.n_dropped} non-finite dropped) -> "
            f"{hilbert_map!r}, {hilbert_map.memory_bytes() / 1e6:.2f} MB, mapped in "
            f"{run.seconds:.1f} s; wrote {output}"
        )
    if live is not None:
        serve_until_stopped(live.server, f"the map at {live.url}")


class FirstInterrupt:
    """Within it, a first Ctrl-C asks the scans to stop after the one being learned (the map
    is then saved whole); a second one stops at once, as Ctrl-C does elsewhere."""

    def __init__(self) -> None:
        self.asked = False
        self._previous = None

    def __enter__(self) -> FirstInterrupt:
        self._previous = signal.signal(signal.SIGINT, self._interrupted)
        return self

    def __exit__(self, *exception) -> None:
        signal.signal(signal.SIGINT, self._previous)

    def _interrupted(self, signum, frame) -> None:
        if self.asked:
            raise KeyboardInterrupt
        self.asked = True
        errors.print("stopping after this scan, then saving (Ctrl-C again stops at once)")

    def until_asked(self, scans: Iterator) -> Iterator:
        """`scans`, until a stop is asked."""
        for scan in scans:
            if self.asked:
                return
            yield scan


# A map whose kernels reach farther than this from every sensor pose, metres, built finer
# than FINE_FOR_FAR metres, is told that outdoor outputs suit a coarser resolution.
FAR_FROM_SENSOR, FINE_FOR_FAR = 50.0, 0.1


def _hint_resolution(hilbert_map) -> None:
    """A note when the map is far finer than its far returns need: long-range returns at a
    fine resolution make exports and distance fields large."""
    from scipy.spatial import cKDTree

    resolution = hilbert_map.config.resolution
    if resolution >= FINE_FOR_FAR or len(hilbert_map.sensor_path) == 0:
        return
    means = hilbert_map.clusters().means
    far = float(cKDTree(hilbert_map.sensor_path).query(means)[0].max())
    if far > FAR_FROM_SENSOR:
        errors.print(
            f"[yellow]note:[/yellow] the map reaches {far:.0f} m from the sensor at "
            f"{resolution:g} m: exports, meshes and distances of it are large or refused; "
            "outdoor LiDAR maps suit --resolution 0.2"
        )


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

    from ehm.io.files import write_atomically
    from ehm.tiles.progress import TileProgressBar

    progress = nullcontext(None) if quiet else TileProgressBar(console)
    with progress as observer:
        report = tiled_map.build(files, scheduler, workers, output, observer)
    write_atomically(settings_path(output, True), tiled_map.config.to_toml().encode())
    if not quiet:
        console.print(
            f"{report.n_scans} scans, {report.n_rays} rays -> {len(report.tiles)} tiles learned "
            f"by {report.workers} workers in {report.seconds:.1f} s (binning "
            f"{report.binning_seconds:.1f} s); {tiled_map!r}; wrote {output}"
        )
