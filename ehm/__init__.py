"""Efficient Hilbert Maps: continuous occupancy maps from range scans.

The public API: HilbertMap, TiledMap (city-scale maps in tiles, learned on Dask), MapConfig,
Scan, load (either kind of map), diff (what changed between two maps), evaluate (the paper's
comparison, ehm.eval), the errors raised for bad input: EhmError and its kinds
(ehm.errors), and AssumptionWarning, what a reader assumed that its input does not say.
Each is imported on first use, so `import ehm` and the command line's help are instant,
and the evaluation is never loaded by a program that does not ask for it.
"""

import logging
import os
from importlib import import_module
from typing import TYPE_CHECKING, Any

# ehm logs each scan learned on logger "ehm" (INFO); an application chooses where it goes.
logging.getLogger(__name__).addHandler(logging.NullHandler())

# Numba's parallel loops run on GNU OpenMP, whose threads spin after each loop, waiting for
# the next, for 300,000 turns unless told otherwise. Learning runs many short loops with Python
# work between them, which spinning threads slow on a machine of few cores; they wait 3,000
# turns here and then sleep, unless the environment sets the count. Set before any loop starts
# OpenMP.
os.environ.setdefault("GOMP_SPINCOUNT", "3000")

if TYPE_CHECKING:
    from ehm.changes import diff
    from ehm.config import MapConfig
    from ehm.core.sensor.scan import Scan
    from ehm.errors import (
        AssumptionWarning,
        EhmError,
        EmptyMapError,
        FileReadError,
        InputError,
        OutputError,
        SettingsError,
    )
    from ehm.eval.runner import evaluate
    from ehm.hilbert_map import HilbertMap
    from ehm.io.map_file import MapFileError
    from ehm.maps import load
    from ehm.tiles.tiled_map import TiledMap

# Each public name and the module that defines it.
_HOMES = {
    "AssumptionWarning": "ehm.errors",
    "EhmError": "ehm.errors",
    "EmptyMapError": "ehm.errors",
    "FileReadError": "ehm.errors",
    "InputError": "ehm.errors",
    "OutputError": "ehm.errors",
    "SettingsError": "ehm.errors",
    "HilbertMap": "ehm.hilbert_map",
    "MapConfig": "ehm.config",
    "MapFileError": "ehm.io.map_file",
    "Scan": "ehm.core.sensor.scan",
    "TiledMap": "ehm.tiles.tiled_map",
    "evaluate": "ehm.eval.runner",
    "load": "ehm.maps",
    "diff": "ehm.changes",
}

__all__ = [
    "AssumptionWarning",
    "EhmError",
    "EmptyMapError",
    "FileReadError",
    "HilbertMap",
    "InputError",
    "MapConfig",
    "MapFileError",
    "OutputError",
    "Scan",
    "SettingsError",
    "TiledMap",
    "diff",
    "evaluate",
    "load",
]
__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module 'ehm' has no attribute {name!r}")
    value = getattr(import_module(_HOMES[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
