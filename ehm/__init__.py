"""Efficient Hilbert Maps: continuous occupancy maps from range scans."""

from ehm.comparison import evaluate
from ehm.config import MapConfig
from ehm.io.map_file import MapFileError, load
from ehm.model import HilbertMap
from ehm.scan import Scan

__all__ = ["HilbertMap", "MapConfig", "MapFileError", "Scan", "evaluate", "load"]
__version__ = "0.1.0"
