"""LAS files for tests, written by laspy: points at millimetre scale, with a coordinate
system record where asked."""

import numpy as np


def write_las(path, points, vlr=None):
    """A LAS 1.2 file of (n, 3) points at `path`, with `vlr` among its records."""
    import laspy

    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.001, 0.001, 0.001])
    las = laspy.LasData(header)
    las.x, las.y, las.z = np.asarray(points).T
    if vlr is not None:
        las.vlrs.append(vlr)
    las.write(path)
    return path


def geo_keys(*pairs):
    """A GeoTIFF key directory record of (key id, value) pairs."""
    from laspy.vlrs.known import GeoKeyDirectoryVlr, GeoKeyEntryStruct

    keys = GeoKeyDirectoryVlr()
    for key_id, value in pairs:
        entry = GeoKeyEntryStruct()
        entry.id, entry.tiff_tag_location, entry.count, entry.value_offset = key_id, 0, 1, value
        keys.geo_keys.append(entry)
    keys.geo_keys_header.number_of_keys = len(keys.geo_keys)
    return keys
