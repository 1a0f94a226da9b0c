"""LAS and LAZ point clouds (airborne and terrestrial LiDAR), read with `laspy` (and `lazrs`
for LAZ): (N, 3) float64 x, y, z in the file's coordinates with its scale and offset applied,
in metres.

Georeferenced files say their units in their coordinate system's records: GeoTIFF keys
(ProjLinearUnitsGeoKey, VerticalUnitsGeoKey) or an OGC WKT. Coordinates in feet (State Plane
systems often use US survey feet) are turned into metres, and the reader says so; files that
record no units are taken as metres.
"""

from __future__ import annotations

import io
import re
import struct
from os import PathLike

import numpy as np

from ehm.errors import FileReadError, assumed
from ehm.io.files import read_input

INSTALL_HINT = "LAS and LAZ files need laspy (and lazrs for LAZ): pip install 'ehm[las]'"
# EPSG's linear units: code -> (name, metres in one).
LINEAR_UNITS = {
    9001: ("metres", 1.0),
    9002: ("feet", 0.3048),
    9003: ("US survey feet", 1200 / 3937),
    9036: ("kilometres", 1000.0),
}
PROJECTED_CS_KEY, PROJ_LINEAR_UNITS_KEY, VERTICAL_UNITS_KEY = 3072, 3076, 4099
UNITS_UNSAID = (
    "its GeoTIFF keys name a projected system but not its units: read as metres; a State Plane "
    "system in feet maps 3.28x too large"
)
_WKT_UNIT = re.compile(r'UNIT\s*\[\s*"([^"]+)"\s*,\s*([0-9.eE+-]+)')


def read_las(path: str | PathLike[str]) -> np.ndarray:
    """(N, 3) float64 points of a LAS or LAZ file; FileReadError naming it when laspy cannot
    read it or it holds no points."""
    try:
        import laspy
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error
    data = read_input(path)
    _check_header(data, path)
    try:
        cloud = laspy.read(io.BytesIO(data))
        points = np.column_stack([np.asarray(cloud.x), np.asarray(cloud.y), np.asarray(cloud.z)])
        vlrs = list(cloud.header.vlrs)
    except Exception as error:
        # laspy and its LAZ backends report bad files in many exception types.
        raise FileReadError(path, f"not a readable LAS/LAZ file ({error!r})") from None
    if len(points) == 0:
        raise FileReadError(path, "no points")
    try:
        (horizontal, h_metres), (vertical, v_metres), source = _units(vlrs)
    except ValueError as error:
        raise FileReadError(path, str(error)) from None
    points = points.astype(np.float64)
    if source == UNITS_UNSAID:
        assumed(f"{path}: {source}")
    elif (h_metres, v_metres) != (1.0, 1.0):
        points *= [h_metres, h_metres, v_metres]
        assumed(
            f"{path}: coordinates in {horizontal} ({h_metres:.10g} m) horizontally and "
            f"{vertical} ({v_metres:.10g} m) vertically, as {source} say: read as metres"
        )
    return points


Unit = tuple[str, float]


def _units(vlrs) -> tuple[Unit, Unit, str]:
    """(horizontal unit, vertical unit, where they were found) of a LAS file's coordinate
    system records, each (name, metres in one); metres where they record none, or
    UNITS_UNSAID where they name a system without its units. ValueError for a unit code this
    reader does not know."""
    metres = LINEAR_UNITS[9001]
    for vlr in vlrs:
        keys = {key.id: key.value_offset for key in getattr(vlr, "geo_keys", [])}
        if PROJ_LINEAR_UNITS_KEY in keys:
            horizontal = _geotiff_unit(keys[PROJ_LINEAR_UNITS_KEY])
            vertical = horizontal
            if VERTICAL_UNITS_KEY in keys:
                vertical = _geotiff_unit(keys[VERTICAL_UNITS_KEY])
            return horizontal, vertical, "its GeoTIFF keys"
        if PROJECTED_CS_KEY in keys:  # units implied by an EPSG code this reader cannot look up
            return metres, metres, UNITS_UNSAID
        # An OGC WKT: a projected system's length unit is its last UNIT before any vertical
        # system (an angular one comes first, in its geographic system).
        wkt = str(getattr(vlr, "string", ""))
        projected, *vertical_part = re.split("VERT_?CS|VERTCRS", wkt, maxsplit=1)
        found = _WKT_UNIT.findall(projected) if "PROJCS" in wkt or "PROJCRS" in wkt else []
        if found:
            horizontal = _wkt_unit(found[-1])
            below = _WKT_UNIT.findall(vertical_part[0]) if vertical_part else []
            return horizontal, _wkt_unit(below[-1]) if below else horizontal, "its WKT"
    return metres, metres, "no coordinate system recorded"


def _geotiff_unit(code: int) -> Unit:
    """The EPSG linear unit `code` names; ValueError for one this reader does not know."""
    if code not in LINEAR_UNITS:
        names = ", ".join(f"{c} ({name})" for c, (name, _) in LINEAR_UNITS.items())
        raise ValueError(f"its GeoTIFF keys give linear unit {code}, not one of {names}")
    return LINEAR_UNITS[code]


def _wkt_unit(found: tuple[str, str]) -> Unit:
    name, factor = found
    return name, float(factor)


def _check_header(data: bytes, path: str | PathLike[str]) -> None:
    """FileReadError for a public header block whose sizes the file cannot hold: a LAS reader
    trusting them would read past the end or loop over records that are not there."""
    if len(data) < 227 or data[:4] != b"LASF":
        raise FileReadError(path, "not a LAS/LAZ file (no LASF header)")
    header_size, point_offset, n_vlrs = struct.unpack_from("<HII", data, 94)
    point_format, record_length, n_points = struct.unpack_from("<BHI", data, 104)
    if data[25] >= 4 and len(data) >= 255:  # LAS 1.4 counts points in 64 bits
        (n_points,) = struct.unpack_from("<Q", data, 247)
    compressed = bool(point_format & 0xC0)
    room = len(data) - point_offset
    if not header_size <= point_offset <= len(data):
        raise FileReadError(path, f"point data at byte {point_offset} outside the file")
    if n_vlrs * 54 > point_offset - header_size:
        raise FileReadError(path, f"{n_vlrs} variable-length records do not fit the header")
    if not compressed and n_points * record_length > room:
        raise FileReadError(
            path,
            f"truncated: {n_points} points of {record_length} bytes announced",
            f"byte {point_offset}",
        )
    if compressed and n_points > 1000 * room:  # LAZ stores a point in well over a byte
        raise FileReadError(path, f"{n_points} points announced in {room} compressed bytes")
