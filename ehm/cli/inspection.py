"""`ehm view`, `ehm info` and `ehm diff`: a map in the browser, what a map file holds, and what
changed between two maps of one place."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ehm.cli.app import (
    Bounds,
    Force,
    MaxGiB,
    Resolution,
    app,
    console,
    grid_bytes,
    load_map,
    output_resolution,
    parse_box,
    serve_until_stopped,
)
from ehm.errors import EmptyMapError, InputError


@app.command()
def view(
    map_path: Annotated[Path, typer.Argument(metavar="MAP", help="Map file.")],
    port: Annotated[int, typer.Option(help="Port of the web page.")] = 8080,
    host: Annotated[
        str, typer.Option(help="Address to serve on (0.0.0.0: every interface).")
    ] = "127.0.0.1",
    resolution: Annotated[float, typer.Option(help="Voxel side of the surface, metres.")] = 0.1,
) -> None:
    """Look at a map in the browser (pip install 'ehm\\[viewer]'): its surface at an occupancy
    level coloured by height or uncertainty, a slice of the occupancy, the samples it keeps,
    the sensor path. Ctrl-C stops the server."""
    from ehm.viz.viewer import MapViewer, viser_module

    if not 0 < port < 65536:
        raise InputError(f"--port must be 1 to 65535, got {port}")
    viser_module()
    hilbert_map = load_map(map_path)
    viewer = MapViewer(hilbert_map, resolution, port, host)
    serve_until_stopped(viewer.server, f"{map_path} at {viewer.url}")


@app.command()
def info(
    map_path: Annotated[Path, typer.Argument(metavar="MAP", help="Map file.")],
    all_settings: Annotated[
        bool, typer.Option("--all", help="Every setting, not only those changed.")
    ] = False,
) -> None:
    """What a map file holds, and the settings it was made with that differ from the
    defaults at its resolution (--all: every setting)."""
    import numpy as np

    hilbert_map = load_map(map_path)
    table = Table(title=str(map_path))
    table.add_column("property")
    table.add_column("value")
    if map_path.is_dir():
        _tiled_map_rows(table, hilbert_map)
        _settings_rows(table, hilbert_map.config, all_settings)
        console.print(table)
        return
    table.add_row("dimensions", str(hilbert_map.dim))
    table.add_row("resolution", f"{hilbert_map.config.resolution:g} m (outputs default to it)")
    table.add_row("clusters", str(hilbert_map.n_clusters))
    table.add_row("scans", str(hilbert_map.n_scans_))
    scale = hilbert_map.model_.scale if hilbert_map.model_ is not None else 1.0
    reading = "calibrated" if hilbert_map.config.calibrate else "raw: calibrate is off"
    table.add_row("log-odds read times", f"{scale:.3g} ({reading})")
    if hilbert_map.time_ is not None:
        table.add_row("latest time stamp", f"{hilbert_map.time_:.3f} s")
    path = hilbert_map.sensor_path
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum()) if len(path) else 0.0
    table.add_row("sensor path", f"{len(path)} poses, {length:.2f} m long")
    table.add_row("memory", f"{hilbert_map.memory_bytes() / 1e6:.3f} MB")
    memory = hilbert_map.model_.memory
    table.add_row("past evidence kept", f"{len(memory)} cells, {memory.weight.sum():.0f} samples")
    table.add_row("file size", f"{map_path.stat().st_size / 1e6:.3f} MB")
    means = hilbert_map.clusters().means
    if hilbert_map.local_origin_ is not None and hilbert_map.local_origin_.any():
        table.add_row("local origin (m)", str(hilbert_map.local_origin_.tolist()))
    if len(means):
        low, high = means.min(axis=0).round(2).tolist(), means.max(axis=0).round(2).tolist()
        table.add_row("cluster extent (m)", f"{low} .. {high}")
    else:
        table.add_row("cluster extent (m)", "none: the map is empty, every point reads 0.5")
    _settings_rows(table, hilbert_map.config, all_settings)
    console.print(table)


def _settings_rows(table: Table, config, every: bool) -> None:
    """A row per setting that differs from MapConfig.for_resolution's at the map's resolution
    (every one when `every`), and a row saying how many are left out."""
    from ehm.config import SECTIONS, MapConfig

    defaults = MapConfig.for_resolution(config.resolution).to_dict()
    same = 0
    for section in SECTIONS:
        for name, value in config.section(section).items():
            if not every and _same_setting(value, defaults[name]):
                same += 1
                continue
            table.add_row(f"{section}.{name}", repr(value))
    if same:
        table.add_row(
            "other settings", f"{same} at their defaults for {config.resolution:g} m (--all)"
        )


def _same_setting(value, default) -> bool:
    """Whether a setting's value is its default (floats to a part in 1e9)."""
    if isinstance(value, float) and isinstance(default, float):
        return math.isclose(value, default, rel_tol=1e-9)
    return value == default


@app.command()
def diff(
    old_path: Annotated[
        Path, typer.Argument(metavar="OLD", help="The older map (file or tiled map folder).")
    ],
    new_path: Annotated[
        Path, typer.Argument(metavar="NEW", help="The newer map of the same place.")
    ],
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Picture to write (.png), seen from above.")
    ],
    points: Annotated[
        Path | None,
        typer.Option(help="Also write the voxel centres (.npz: appeared, vanished, stayed)."),
    ] = None,
    resolution: Resolution = None,
    bounds: Bounds = None,
    occupied: Annotated[
        float | None,
        typer.Option(help="Occupied at or above this p(occupied) \\[default: map_server's, 0.65]."),
    ] = None,
    free: Annotated[
        float | None,
        typer.Option(help="Free at or below this p(occupied) \\[default: map_server's, 0.196]."),
    ] = None,
    max_gib: MaxGiB = 1.0,
    force: Force = False,
) -> None:
    """What changed between two maps of one place: the voxels that became occupied (free in
    the old map) and those that became free; voxels either map has not seen are no change."""
    import numpy as np

    from ehm.changes import diff as map_diff
    from ehm.io.output_paths import check_output
    from ehm.viz.pictures import changes_picture

    check_output(output, [old_path, new_path], force, suffix=".png")
    if points is not None:
        check_output(points, [old_path, new_path, output], force, suffix=".npz")
    max_bytes = grid_bytes(max_gib)
    old, new = load_map(old_path), load_map(new_path)
    levels = {"occupied": occupied, "free": free}
    changes = map_diff(
        old,
        new,
        output_resolution(new, resolution),
        parse_box(new, bounds),
        max_bytes=max_bytes,
        **{name: level for name, level in levels.items() if level is not None},
    )
    changes_picture(changes, output, f"{old_path.name} to {new_path.name}")
    console.print(f"{changes!r}\nwrote {output}")
    if points is not None:
        np.savez(
            points, appeared=changes.appeared, vanished=changes.vanished, stayed=changes.stayed
        )
        console.print(f"wrote {points}")


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
