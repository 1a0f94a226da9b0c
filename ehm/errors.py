"""The errors `ehm` raises for mistakes in what it is given: input data, settings, options and
files. Each is a ValueError, so code that caught ValueError before still does; any other
exception out of `ehm` is a bug.

    try:
        scans = read_scans("scan.pcd")
    except ehm.EhmError as error:
        print(error)        # scan.pcd, byte 212: truncated: 5000 points announced, 31 found
"""

from __future__ import annotations

import warnings
from os import PathLike


class EhmError(ValueError):
    """A mistake in what `ehm` was given; the message says what, where and what was expected."""


class SettingsError(EhmError):
    """A setting (MapConfig) or option outside its type or range."""


class InputError(EhmError):
    """Arrays, scans or arguments that cannot be used: wrong shape, frame, range or state."""


class EmptyMapError(InputError):
    """A map asked for something it does not have yet: it has learned from no scan."""


class FileReadError(EhmError):
    """A file that cannot be read as what it claims to be: missing, foreign, truncated or
    corrupt. `path` is the file, `where` the line ("line 12") or byte ("byte 4096") if known."""

    def __init__(self, path: str | PathLike[str], message: str, where: str | None = None):
        self.path = str(path)
        self.where = where
        super().__init__(f"{path}{', ' + where if where else ''}: {message}")


class OutputError(EhmError):
    """An output path that cannot or may not be written: missing folder, existing file without
    `force`, or one of the inputs."""


class AssumptionWarning(UserWarning):
    """A reader assumed something its input does not record (a camera, units, a frame); the
    message says what it assumed and how to say otherwise. The command line prints these as
    `note:` lines."""


def assumed(message: str) -> None:
    """Say what a reader assumed that its input does not record (an AssumptionWarning)."""
    warnings.warn(message, AssumptionWarning, stacklevel=3)
