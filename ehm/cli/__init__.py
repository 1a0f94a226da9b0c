"""The `ehm` command: demo and map (ehm.cli.mapping), query, grid, mesh, render and export
(ehm.cli.outputs), view and info (ehm.cli.inspection), eval (ehm.cli.evaluation), on the group
and helpers of ehm.cli.app. Heavy imports happen inside each command so that `ehm --help` is
instant.

A mistake in the input (ehm.EhmError: a file that cannot be read, a bad setting or option, an
output that may not be written) ends in one line, `error: ...`, on stderr and exit status 2,
before any work where it can be checked first. Anything else is a bug: one line and exit
status 1, or its traceback with `ehm --debug`."""

# Imported in the order `ehm --help` lists their commands.
from ehm.cli import mapping, outputs, inspection, evaluation  # noqa: I001
from ehm.cli.app import app

__all__ = ["app", "evaluation", "inspection", "mapping", "outputs"]
