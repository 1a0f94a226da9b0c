"""Efficient Hilbert Maps: continuous occupancy maps from range scans.

The public API: HilbertMap, MapConfig, Scan, load and MapFileError. The paper's evaluation
(ehm.eval) is not imported with the package; `ehm.evaluate` loads it on first use.
"""

from typing import Any

from ehm.config import MapConfig
from ehm.core.scan import Scan
from ehm.hilbert_map import HilbertMap, load
from ehm.io.map_file import MapFileError

__all__ = ["HilbertMap", "MapConfig", "MapFileError", "Scan", "evaluate", "load"]
__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    if name == "evaluate":
        from ehm.eval.runner import evaluate

        return evaluate
    raise AttributeError(f"module 'ehm' has no attribute {name!r}")
