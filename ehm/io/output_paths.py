"""Checking output paths before any work: a run's result is never lost to a path that cannot
be written, and never written over one of its inputs."""

from __future__ import annotations

import os
from collections.abc import Sequence
from os import PathLike
from pathlib import Path

from ehm.errors import OutputError


def check_output(
    path: str | PathLike[str],
    inputs: Sequence[str | PathLike[str]] = (),
    force: bool = False,
    suffix: str | None = None,
) -> Path:
    """`path` as a Path once it is known to be writable: its folder exists and can be written,
    it is not a folder, not one of `inputs` (even with `force`), does not exist unless
    `force`, and ends in `suffix` when one is given. OutputError naming the problem otherwise."""
    path = Path(path)
    if suffix is not None and path.suffix.lower() != suffix:
        raise OutputError(f"{path}: expected a name ending in {suffix}")
    if path.is_dir():
        raise OutputError(f"{path} is a folder: expected a file name")
    folder = path.parent
    if not folder.exists():
        raise OutputError(f"{path}: folder {folder} does not exist")
    if not folder.is_dir():
        raise OutputError(f"{path}: {folder} is a file, not a folder")
    if path.exists():
        for item in inputs:
            if Path(item).exists() and path.samefile(item):
                raise OutputError(f"{path} is an input: writing it would destroy it")
        if not force:
            raise OutputError(f"{path} exists: --force overwrites it")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"{path}: folder {folder} cannot be written")
    return path


def check_output_folder(path: str | PathLike[str]) -> Path:
    """`path` as a Path once it is a folder or can be made one: OutputError when it is a file or
    lies under one."""
    path = Path(path)
    for folder in (path, *path.parents):
        if folder.exists():
            if not folder.is_dir():
                raise OutputError(f"{path}: {folder} is a file, not a folder")
            if not os.access(folder, os.W_OK):
                raise OutputError(f"{path}: folder {folder} cannot be written")
            return path
    return path


def check_output_map_directory(
    path: str | PathLike[str], inputs: Sequence[str | PathLike[str]] = (), force: bool = False
) -> Path:
    """`path` as a Path once a tiled map's directory can be written there: its folder exists
    and can be written; it is not a file; not one of `inputs`; and if it exists, it is an empty
    folder, or with `force` one holding a tiled map (index.json) to write over. OutputError
    naming the problem otherwise."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{path} is a file: a tiled map is written as a folder")
    folder = path.parent
    if not folder.is_dir():
        raise OutputError(f"{path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise OutputError(f"{path}: folder {folder} cannot be written")
    if path.is_dir() and any(path.iterdir()):
        for item in inputs:
            item = Path(item)
            if item.exists() and (path.samefile(item) or path.resolve() in item.resolve().parents):
                raise OutputError(f"{path} holds an input: writing it would destroy it")
        if not (path / "index.json").is_file():
            raise OutputError(f"{path} is a folder of other files: choose a new or empty folder")
        if not force:
            raise OutputError(f"{path} exists: --force overwrites it")
    return path
