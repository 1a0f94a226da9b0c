"""The `ehm` command group and what its commands share: errors turned into one line, the
consoles, option types, and parsing of settings, boxes and lists."""

from __future__ import annotations

import inspect
import logging
import math
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table
from typer.core import TyperGroup

from ehm.errors import EhmError, InputError, OutputError


class _Commands(TyperGroup):
    """The command group: turns ehm's errors into one line on stderr (see the module), and
    what readers assume into `note:` lines, as they come."""

    def get_command(self, ctx: Any, name: str) -> Any:
        """The command, its docstring's lines joined into paragraphs, which Rich then wraps to
        the terminal (else each source line breaks the help text)."""
        command = super().get_command(ctx, name)
        if command is not None and command.help:
            paragraphs = inspect.cleandoc(command.help).split("\n\n")
            command.help = "\n\n".join(" ".join(p.split()) for p in paragraphs)
        return command

    def invoke(self, ctx: Any) -> Any:
        try:
            with reported_assumptions():
                return super().invoke(ctx)
        except (EhmError, ImportError) as error:
            # An ImportError is a mistake only where an optional part is missing (its message
            # names the extra to install); any other is a bug.
            optional = isinstance(error, ImportError) and "pip install 'ehm[" in str(error)
            if ctx.params.get("debug") or not (isinstance(error, EhmError) or optional):
                raise
            errors.print(f"[red]error:[/red] {escape(str(error))}")
            cli_log.error("error: %s", error)
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


def _show_version(asked: bool) -> None:
    """Print the version and stop, for --version."""
    if asked:
        from importlib.metadata import version

        typer.echo(f"ehm {version('ehm')}")
        raise typer.Exit()


@app.callback()
def _options(
    debug: Annotated[
        bool, typer.Option("--debug", help="Show the Python traceback of any error.")
    ] = False,
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_show_version, is_eager=True, help="Show the version and stop."
        ),
    ] = False,
    verbose: Annotated[
        bool,
        typer.Option("--verbose", "-v", help="Log each scan learned and each step, on stderr."),
    ] = False,
    log: Annotated[
        Path | None,
        typer.Option(
            help="Append the log (each scan learned, notes, errors), time-stamped, to this file."
        ),
    ] = None,
) -> None:
    """Efficient Hilbert Maps: continuous occupancy maps from range scans."""
    configure_logging(verbose, log)


# Lines of the log file: when, how grave, which part of ehm, what.
LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
# What the command line prints itself (notes, errors) goes to the log file only: on stderr it
# is shown already.
cli_log = logging.getLogger("ehm.cli")


def configure_logging(verbose: bool, log_file: Path | None) -> None:
    """Route ehm's log (logger 'ehm') to stderr with `verbose`, and to `log_file` (appended)
    when given; neither: nothing is logged."""
    logger = logging.getLogger("ehm")
    for handler in list(logger.handlers):  # one command a process, but tests invoke many
        logger.removeHandler(handler)
        handler.close()
    logger.setLevel(logging.INFO if verbose or log_file else logging.WARNING)
    logger.addHandler(logging.NullHandler())  # else Python prints warnings on its own
    if verbose:
        from rich.logging import RichHandler

        shown = RichHandler(console=errors, show_path=False, log_time_format="%H:%M:%S")
        shown.addFilter(lambda record: not record.name.startswith(cli_log.name))
        logger.addHandler(shown)
    if log_file is not None:
        try:
            written = logging.FileHandler(log_file, encoding="utf-8")
        except OSError as error:
            raise OutputError(f"--log {log_file}: {error.strerror}") from None
        written.setFormatter(logging.Formatter(LOG_FORMAT))
        logger.addHandler(written)


Resolution = Annotated[
    float | None,
    typer.Option(help="Voxel side of the grid, metres.  \\[default: the map's resolution]"),
]


def output_resolution(any_map, resolution: float | None) -> float:
    """`resolution`, metres, or the map's own (MapConfig.resolution) when None; InputError
    unless it is a positive number."""
    chosen = any_map.config.resolution if resolution is None else resolution
    if not 0.0 < chosen < math.inf:
        raise InputError(f"--resolution must be a positive number of metres, got {chosen}")
    return chosen


Bounds = Annotated[
    str | None,
    typer.Option(
        help="Grid box 'x0,y0,z0,x1,y1,z1' (2D: 'x0,y0,x1,y1'), metres; default: all of the map."
    ),
]


MaxGiB = Annotated[float, typer.Option(help="Refuse grids larger than this, GiB.")]


Level = Annotated[float, typer.Option(help="Occupancy probability of the surface.")]


Force = Annotated[bool, typer.Option("--force", help="Overwrite output files that exist.")]


def parse_settings(settings: list[str]) -> dict:
    """`name=value` pairs into MapConfig overrides, values typed like the defaults."""
    from ehm.config import MapConfig

    defaults = MapConfig().to_dict()
    overrides = {}
    for item in settings:
        name, sep, value = item.partition("=")
        if not sep or name not in defaults:
            raise InputError(f"--set {item!r}: expected name=value with a MapConfig name")
        # A setting off by default (None) takes a value of its type, or none.
        kind = MapConfig.setting_type(name) if defaults[name] is None else type(defaults[name])
        if MapConfig.may_be_off(name) and value.lower() == "none":
            overrides[name] = None
        elif kind is bool:
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


def load_map(path: Path):
    """The map at `path`, a file or a tiled map's directory (ehm.load)."""
    from ehm.maps import load

    return load(path)


def parse_box(hilbert_map, bounds: str | None):
    """(2, d) float64 bounds from 'x0,y0,..' text, or None."""
    import numpy as np

    if bounds is None:
        return None
    box = np.array(parse_numbers(bounds, float, "--bounds"))
    if len(box) != 2 * hilbert_map.dim:
        raise InputError(
            f"--bounds: {2 * hilbert_map.dim} numbers for a {hilbert_map.dim}D map, got {len(box)}"
        )
    return box.reshape(2, hilbert_map.dim)


def map_grid(hilbert_map, box, resolution: float | None, max_gib: float, std: bool = False):
    """The map's grid over `box` ((2, d) or None: all of the map) at `resolution` (None: the
    map's own), with the std when asked."""
    voxel = output_resolution(hilbert_map, resolution)
    return hilbert_map.grid(box, voxel, max_bytes=grid_bytes(max_gib), std=std)


def map_mesh(any_map, box, resolution: float, level: float, max_gib: float):
    """Vertices (V, 3) and faces (F, 3) where a 3D map's occupancy crosses `level`, over `box`
    as in map_blocks: block by block for a map, from one grid for a tiled map."""
    from ehm.grid.blocks import block_mesh
    from ehm.hilbert_map import HilbertMap

    if isinstance(any_map, HilbertMap):
        return block_mesh(any_map.snapshot(), resolution, box, level, grid_bytes(max_gib))
    return any_map.grid(box, resolution, max_bytes=grid_bytes(max_gib)).mesh(level)


def grid_bytes(max_gib: float) -> int:
    """--max-gib in bytes; InputError unless it is a positive number."""
    if not 0 < max_gib < math.inf:
        raise InputError(f"--max-gib must be a positive number, got {max_gib}")
    return int(max_gib * 2**30)


def progress_bar():
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    return Progress(
        "[progress.description]{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
    )


def timings_table(title: str, seconds: dict[str, float]) -> Table:
    table = Table(title=title)
    table.add_column("stage")
    table.add_column("time (ms)", justify="right")
    for stage, value in seconds.items():
        table.add_row(stage, f"{1000 * value:.1f}")
    table.add_row("[bold]total", f"[bold]{1000 * sum(seconds.values()):.1f}")
    return table


def parse_names(text: str, known: list[str], what: str) -> list[str]:
    """Comma-separated names; 'all' stands for every known one."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return list(known)
    if not names:
        raise InputError(f"no {what} given")
    return names


def parse_numbers(text: str, kind: type, what: str) -> list:
    """Comma-separated finite numbers of `kind`; InputError naming `what` and the text."""
    try:
        values = [kind(v) for v in text.split(",") if v.strip()]
    except ValueError as error:
        raise InputError(f"{what}: {error}") from error
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{what}: expected finite numbers, got {text!r}")
    return values


@contextmanager
def reported_assumptions() -> Iterator[None]:
    """Print each ehm.AssumptionWarning raised inside as a `note:` line on stderr, as it comes:
    what a reader assumed that its input does not record."""
    from ehm.errors import AssumptionWarning

    shown = warnings.showwarning

    def note(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, AssumptionWarning):
            errors.print(f"[yellow]note:[/yellow] {escape(str(message))}")
            cli_log.warning("note: %s", message)
        else:
            shown(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        warnings.simplefilter("always", AssumptionWarning)
        warnings.showwarning = note
        yield


def serve_until_stopped(server, what: str) -> None:
    """Keep a viewer's server running until Ctrl-C."""

    console.print(f"showing {what} (Ctrl-C stops)")
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        server.stop()
