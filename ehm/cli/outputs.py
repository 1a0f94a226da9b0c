"""`ehm query`, `grid`, `mesh`, `render` and `export`: what a map answers and what is made of it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from ehm.cli.app import (
    Bounds,
    Force,
    Level,
    MaxGiB,
    Resolution,
    app,
    console,
    errors,
    grid_bytes,
    load_map,
    map_grid,
    map_mesh,
    output_resolution,
    parse_box,
)
from ehm.errors import InputError

Unknown = Annotated[
    str,
    typer.Option(
        help="With --distance: space no ray has reached is an obstacle (occupied), as rays "
        "stop at it, or free.",
    ),
]


def check_unknown(unknown: str, distance: bool) -> None:
    """InputError for an --unknown that is not a rule, or given without --distance."""
    if unknown not in ("occupied", "free"):
        raise InputError(f"--unknown must be occupied or free, got {unknown!r}")
    if unknown != "occupied" and not distance:
        raise InputError("--unknown goes with --distance")


@app.command()
def query(
    map_path: Annotated[Path, typer.Argument(metavar="MAP", help="Map file.")],
    points: Annotated[
        Path,
        typer.Argument(
            metavar="POINTS",
            help="Points: .npy (n, d) or comma-separated text, d numbers a line.",
        ),
    ],
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Write .npy or .csv; default stdout.")
    ] = None,
    mode: Annotated[str | None, typer.Option(help="batch or exact.")] = None,
    std: Annotated[
        bool, typer.Option("--std", help="Also the standard deviation: columns p, std.")
    ] = False,
    distance: Annotated[
        bool,
        typer.Option(
            "--distance",
            help="Also the signed distance, metres, to the nearest point whose occupancy "
            "reaches 0.5 (negative inside): the last column.",
        ),
    ] = False,
    unknown: Unknown = "occupied",
    force: Force = False,
) -> None:
    """Occupancy probability of each point (with --std its standard deviation, with
    --distance its distance to obstacles)."""
    import numpy as np

    from ehm.io.output_paths import check_output
    from ehm.io.points import read_points

    if mode not in (None, "batch", "exact"):
        raise InputError(f"--mode must be batch or exact, got {mode!r}")
    check_unknown(unknown, distance)
    if output is not None:
        check_output(output, [map_path, points], force)
    hilbert_map = load_map(map_path)
    asked = read_points(points, hilbert_map.dim)
    answers = hilbert_map.occupancy(asked, mode=mode, return_std=std)
    answers = list(answers) if std else [answers]
    if distance:
        answers.append(hilbert_map.distance(asked, unknown=unknown))
    columns = np.column_stack(answers) if len(answers) > 1 else answers[0]
    if output is None:
        typer.echo("\n".join(",".join(f"{v:.6f}" for v in np.atleast_1d(row)) for row in columns))
    elif output.suffix == ".npy":
        np.save(output, columns)
    else:
        np.savetxt(output, columns, fmt="%.6f", delimiter=",")


@app.command()
def grid(
    map_path: Annotated[Path, typer.Argument(metavar="MAP", help="Map file.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Grid file to write (.npz).")],
    resolution: Resolution = None,
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
    from ehm.io.output_paths import check_output

    check_output(output, [map_path], force, suffix=".npz")
    hilbert_map = load_map(map_path)
    occupancy_grid = map_grid(hilbert_map, parse_box(hilbert_map, bounds), resolution, max_gib, std)
    save_grid(occupancy_grid, output)
    console.print(f"{occupancy_grid!r}\nwrote {output}")


@app.command()
def mesh(
    map_path: Annotated[Path, typer.Argument(metavar="MAP", help="Map file (3D).")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Mesh file to write (.ply).")],
    resolution: Resolution = None,
    bounds: Bounds = None,
    level: Level = 0.5,
    max_gib: MaxGiB = 1.0,
    force: Force = False,
) -> None:
    """Surface mesh of a 3D map by marching cubes, as binary PLY coloured by height."""
    from ehm.io.output_paths import check_output
    from ehm.io.ply import write_ply_mesh
    from ehm.viz.colors import vertex_colors

    check_output(output, [map_path], force, suffix=".ply")
    hilbert_map = load_map(map_path)
    if hilbert_map.dim != 3:
        raise InputError(
            f"{map_path}: a 2D map has no surface mesh: 'ehm render' draws it as a PNG and "
            "'ehm grid' saves its grid"
        )
    voxel = output_resolution(hilbert_map, resolution)
    box = parse_box(hilbert_map, bounds)
    vertices, faces = map_mesh(hilbert_map, box, voxel, level, max_gib)
    if len(faces) == 0:
        raise InputError(f"nothing to mesh: the map does not cross {level} in these bounds")
    write_ply_mesh(output, vertices, faces, vertex_colors(vertices))
    console.print(f"{len(vertices)} vertices, {len(faces)} faces\nwrote {output}")


@app.command()
def render(
    map_path: Annotated[Path, typer.Argument(metavar="MAP", help="Map file.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Picture to write (.png).")],
    resolution: Resolution = None,
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
    from ehm.io.output_paths import check_output
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
    hilbert_map = load_map(map_path)
    if hilbert_map.dim == 2:
        occupancy_grid = map_grid(hilbert_map, parse_box(hilbert_map, bounds), resolution, max_gib)
        grid_picture(occupancy_grid, output, title=map_path.name)
        low, high = occupancy_grid.bounds
    else:
        voxel = output_resolution(hilbert_map, resolution)
        box = parse_box(hilbert_map, bounds)
        vertices, faces = map_mesh(hilbert_map, box, voxel, level, max_gib)
        mesh_picture(vertices, faces, output, camera, cut_above, title=map_path.name)
        low, high = hilbert_map.extent() if box is None else box
    if slices is not None:
        occupancy_slices(hilbert_map, low, high, slices)
    if std is not None:
        occupancy_slices(hilbert_map, low, high, std, std=True)
    console.print("wrote " + " and ".join(str(p) for p in written))


@app.command()
def export(
    map_path: Annotated[Path, typer.Argument(metavar="MAP", help="Map file.")],
    output: Annotated[
        Path,
        typer.Option(
            "--output",
            "-o",
            help="File to write, by its suffix: .ot (OctoMap, log-odds), .bt (OctoMap, "
            "occupied or free), .pgm (+ .yaml, ROS map_server; a 3D map's height band "
            "projected), .ply or .pcd (occupied voxel centres), .npz with --distance.",
        ),
    ],
    resolution: Resolution = None,
    bounds: Bounds = None,
    level: Annotated[
        float,
        typer.Option(help="Occupancy above which a voxel is occupied (.ply, .pcd, --distance)."),
    ] = 0.5,
    distance: Annotated[
        bool,
        typer.Option(
            "--distance",
            help="Write .npz: the signed distance, metres, from each voxel centre to the "
            "nearest point whose occupancy reaches --level, and its gradient "
            "(ehm.io.distance_file).",
        ),
    ] = False,
    unknown: Unknown = "occupied",
    z_min: Annotated[
        float | None,
        typer.Option(
            help="With .pgm from a 3D map: the lowest height projected, metres (default: "
            "0.3 m above the floor under the first sensor pose)."
        ),
    ] = None,
    z_max: Annotated[
        float | None,
        typer.Option(
            help="With .pgm from a 3D map: the highest height projected, metres (default: "
            "2 m above that floor)."
        ),
    ] = None,
    max_gib: MaxGiB = 1.0,
    force: Force = False,
) -> None:
    """Export a map's grid for robotics tools: OctoMap trees that octovis and octomap_server
    open, map_server maps for nav2, point clouds of the occupied voxels, distance fields for
    trajectory optimisers. The bounds widen to multiples of the resolution, so the voxels are
    OctoMap's."""
    import numpy as np

    from ehm.grid.bounds import aligned_bounds
    from ehm.io import exports
    from ehm.io.output_paths import check_output

    suffixes = (*exports.OCTOMAP_SUFFIXES, ".pgm", ".ply", ".pcd", ".npz")
    if output.suffix.lower() not in suffixes:
        raise InputError(f"{output}: expected a name ending in {', '.join(suffixes)}")
    if distance != (output.suffix.lower() == ".npz"):
        raise InputError(
            "--distance writes .npz files, and an .npz export is a distance field: give both "
            "(`ehm grid` writes occupancy grids)"
        )
    check_unknown(unknown, distance)
    if (z_min, z_max) != (None, None) and output.suffix.lower() != ".pgm":
        raise InputError("--z-min and --z-max choose the heights a .pgm export projects")
    check_output(output, [map_path], force)
    if output.suffix == ".pgm":
        check_output(output.with_suffix(".yaml"), [map_path], force)
    hilbert_map = load_map(map_path)
    resolution = output_resolution(hilbert_map, resolution)
    box = parse_box(hilbert_map, bounds)
    aligned = aligned_bounds(hilbert_map.extent() if box is None else box, resolution)
    if distance:
        _export_distance(hilbert_map, aligned, resolution, level, unknown, max_gib, output)
        return
    if output.suffix == ".pgm":
        _export_map_server(hilbert_map, aligned, resolution, (z_min, z_max), max_gib, output)
        return
    grids = hilbert_map.grid_blocks(
        None if box is None else aligned, resolution, max_bytes=grid_bytes(max_gib)
    )
    if output.suffix in exports.OCTOMAP_SUFFIXES:
        grids = _near_octomap_origin(hilbert_map, grids)
        known = exports.write_octomap(grids, output, grid_bytes(max_gib))
        console.print(f"{known} known voxels of {resolution:g} m\nwrote {output}")
    else:
        points = np.concatenate(
            [np.zeros((0, hilbert_map.dim))]
            + [exports.occupied_voxels(grid, level) for grid in grids]
        )
        if hilbert_map.dim == 2:
            points = np.column_stack([points, np.zeros(len(points))])
        exports.write_point_cloud(points, output)
        console.print(f"{len(points)} occupied voxels\nwrote {output}")


def _near_octomap_origin(any_map, grids):
    """The grids of a map kept around a far local origin (HilbertMap.local_origin_:
    georeferenced data) moved by minus that origin, with a note: OctoMap's keys reach 2^15
    voxels from a tree's origin; other grids as they are."""
    offset = getattr(any_map, "local_origin_", None)
    if offset is None or not offset.any():
        return grids
    errors.print(
        f"[yellow]note:[/yellow] the tree is written relative to {offset.tolist()} m, the map's "
        "local origin, as OctoMap's keys reach only 32768 voxels from a tree's origin: add it "
        "back to the tree's coordinates"
    )

    def moved(grid):
        grid.origin = grid.origin - offset  # each block is made for this export alone
        return grid

    return map(moved, grids)


def _export_map_server(
    any_map, bounds, resolution: float, heights, max_gib: float, output: Path
) -> None:
    """Write the map's navigation grid (ehm.grid.navigation) as a map_server map: a 2D map's
    own, a 3D map's band of `heights` (z_min, z_max; None each: the default band) projected."""
    from ehm.grid.navigation import (
        FREE,
        OCCUPIED,
        default_heights,
        navigation_grid,
        projected_navigation_grid,
    )
    from ehm.io import exports

    if any_map.dim == 3:
        if None in heights:
            defaults = default_heights(any_map, resolution)
            heights = tuple(d if h is None else h for h, d in zip(heights, defaults, strict=True))
        grid = projected_navigation_grid(
            any_map, heights, bounds[:, :2], resolution, grid_bytes(max_gib)
        )
    else:
        if heights != (None, None):
            raise InputError("--z-min and --z-max choose a 3D map's heights; this map is 2D")
        grid = navigation_grid(any_map, bounds, resolution, grid_bytes(max_gib))
    yaml_path = exports.write_map_server(grid, output)
    shares = ", ".join(
        f"{name} {(grid.states == state).mean():.0%}"
        for name, state in (("free", FREE), ("occupied", OCCUPIED))
    )
    console.print(f"{' x '.join(map(str, grid.shape))} cells of {resolution} m: {shares}")
    console.print(f"wrote {output} and {yaml_path}")


def _export_distance(
    any_map,
    bounds,
    resolution: float,
    level: float,
    unknown: str,
    max_gib: float,
    output: Path,
) -> None:
    """Write the signed distances of `any_map` at the centres of the voxels of `bounds` ((2, d)
    metres) to `output` (.npz), unknown space an obstacle or free (`unknown`)."""
    from ehm.grid.bounds import grid_shape
    from ehm.io.distance_file import DistanceGrid, save_distance_grid

    dim = any_map.dim
    # Per voxel: its centre, distance and gradient, float64.
    origin, shape = grid_shape(bounds, resolution, dim, grid_bytes(max_gib), 8 * (1 + 2 * dim))
    field = DistanceGrid.at_centres(any_map, origin, resolution, shape, level, unknown)
    save_distance_grid(field, output)
    voxels = " x ".join(str(n) for n in shape)
    near, far = field.distance.min(), field.distance.max()
    console.print(f"{voxels} voxels of {resolution:g} m, distances {near:.2f} to {far:.2f} m")
    console.print(f"wrote {output}")
