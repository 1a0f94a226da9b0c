"""LAS and LAZ point clouds written by laspy, read back."""

import numpy as np
import pytest
from las_files import geo_keys, write_las

from ehm.errors import FileReadError
from ehm.io.readers import read_scans

laspy = pytest.importorskip("laspy")


@pytest.mark.parametrize("name", ["cloud.las", "cloud.laz"])
def test_las_and_laz_read_back_to_their_scale(tmp_path, cloud, name):
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.array([100.0, 200.0, 0.0])
    las = laspy.LasData(header)
    shifted = cloud + np.array([100.0, 200.0, 0.0])
    las.x, las.y, las.z = shifted.T
    las.write(tmp_path / name)
    (scan,) = read_scans(tmp_path / name, origin=[100.0, 200.0, 1.5])
    np.testing.assert_allclose(scan.points_world, shifted, atol=0.0005 + 1e-9)
    np.testing.assert_array_equal(scan.origin, [100.0, 200.0, 1.5])


def test_broken_las_files_are_named(tmp_path):
    (tmp_path / "junk.las").write_bytes(b"LASF" + bytes(300))
    with pytest.raises(FileReadError, match=r"junk\.las: not a readable LAS/LAZ file"):
        read_scans(tmp_path / "junk.las")


@pytest.mark.parametrize(
    ("offset", "value", "message"),
    [
        (100, 10**6, "variable-length records do not fit the header"),
        (107, 10**9, "byte 227: truncated: 1000000000 points of 34 bytes announced"),
        (96, 10**8, "point data at byte 100000000 outside the file"),
    ],
)
def test_las_headers_the_file_cannot_hold_are_named(tmp_path, cloud, offset, value, message):
    """Sizes in the header are checked before laspy reads (bit flips there made it loop)."""
    header = laspy.LasHeader(point_format=3, version="1.2")
    las = laspy.LasData(header)
    las.x, las.y, las.z = cloud.T
    las.write(tmp_path / "good.las")
    data = bytearray((tmp_path / "good.las").read_bytes())
    data[offset : offset + 4] = value.to_bytes(4, "little")
    (tmp_path / "bad.las").write_bytes(bytes(data))
    with pytest.raises(FileReadError, match=message):
        read_scans(tmp_path / "bad.las")


def test_feet_are_read_as_metres_and_said(tmp_path, cloud):
    """State Plane tiles in US survey feet (GeoTIFF keys 3076 and 4099 = EPSG unit 9003)."""
    from ehm.errors import AssumptionWarning

    keys = geo_keys((1024, 1), (3072, 2903), (3076, 9003), (4099, 9003))
    path = write_las(tmp_path / "feet.las", cloud, keys)
    with pytest.warns(AssumptionWarning, match=r"US survey feet \(0\.3048006096 m\) horiz"):
        (scan,) = read_scans(path)
    np.testing.assert_allclose(scan.points_world, cloud * 1200 / 3937, atol=0.001)


def test_units_a_file_does_not_say_are_said_and_unknown_ones_refused(tmp_path, cloud):
    from ehm.errors import AssumptionWarning

    unsaid = write_las(tmp_path / "unsaid.las", cloud, geo_keys((1024, 1), (3072, 2903)))
    with pytest.warns(AssumptionWarning, match="name a projected system but not its units"):
        (scan,) = read_scans(unsaid)
    np.testing.assert_allclose(scan.points_world, cloud, atol=0.001)
    odd = write_las(tmp_path / "odd.las", cloud, geo_keys((3072, 2903), (3076, 9030)))
    with pytest.raises(FileReadError, match=r"odd\.las: its GeoTIFF keys give linear unit 9030"):
        read_scans(odd)


def test_a_wkt_in_metres_needs_no_note_and_one_in_feet_is_scaled(tmp_path, cloud):
    import warnings

    from laspy.vlrs.known import WktCoordinateSystemVlr

    from ehm.errors import AssumptionWarning

    geographic = 'GEOGCS["NAD83",DATUM["D",SPHEROID["GRS 1980",6378137,298.257222101]],'
    geographic += 'UNIT["degree",0.0174532925199433]]'
    metres = f'PROJCS["UTM 13N",{geographic},UNIT["metre",1]]'
    path = write_las(tmp_path / "m.las", cloud, WktCoordinateSystemVlr(metres))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (scan,) = read_scans(path)
    np.testing.assert_allclose(scan.points_world, cloud, atol=0.001)
    feet = (
        f'COMPD_CS["x",PROJCS["SP",{geographic},UNIT["foot",0.3048]],VERT_CS["h",UNIT["metre",1]]]'
    )
    path = write_las(tmp_path / "ft.las", cloud, WktCoordinateSystemVlr(feet))
    with pytest.warns(AssumptionWarning, match=r"foot \(0\.3048 m\) horizontally and metre \(1 m"):
        (scan,) = read_scans(path)
    np.testing.assert_allclose(scan.points_world, cloud * [0.3048, 0.3048, 1.0], atol=0.001)


def test_the_shared_state_plane_tile_is_61_metres_across():
    """PDAL's 4_6_crop.las (EPSG:2903, US survey feet): 200 ft = 61 m a side, 19 m of relief."""
    from ehm.errors import AssumptionWarning
    from ehm.eval.datasets.real import data_dir
    from ehm.io.las import read_las

    path = data_dir() / "las_georeferenced" / "4_6_crop.las"
    if not path.exists():
        pytest.skip(f"{path} not found (set EHM_DATA_DIR to the data folder)")
    with pytest.warns(AssumptionWarning, match="US survey feet"):
        points = read_las(path)
    extent = points.max(axis=0) - points.min(axis=0)
    np.testing.assert_allclose(extent, [60.95, 60.95, 18.83], atol=0.01)
