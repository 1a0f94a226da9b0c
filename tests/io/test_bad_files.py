"""Every input file that cannot be read ends in a FileReadError naming the file and, where it
can, the line or byte, and what was expected."""

import bz2
import gzip
import re

import numpy as np
import pytest

from ehm.errors import EhmError, FileReadError, InputError
from ehm.io.readers import read_scans


def test_every_valid_input_reads(input_files):
    for name, (path, options) in input_files.items():
        scans = read_scans(path, **options)
        assert scans and all(len(scan) > 0 for scan in scans), name


def fails(path, message, **options):
    with pytest.raises(FileReadError, match=message) as caught:
        read_scans(path, **options)
    assert caught.value.path == str(path) or str(path) in str(caught.value)
    return caught.value


@pytest.mark.parametrize(
    ("name", "data", "message"),
    [
        ("empty.xyz", b"", "no points"),
        ("words.xyz", b"1 2 3\nx y z\n", r"expected 'x y z' numbers on each line"),
        ("short.xyz", b"1 2\n", r"expected 'x y z' numbers"),
        ("latin.xyz", b"1 2 3\n\xff\xfe\n", r"byte 6: not a text file"),
        ("garbage.dat.bz2", b"not bzip2 at all", "not a bzip2 stream"),
        ("truncated.dat.bz2", bz2.compress(b"1 2 3\n" * 100)[:-20], "truncated bzip2 stream"),
        ("garbage.log.gz", b"not gzip at all", "not a gzip stream"),
        ("truncated.log.gz", gzip.compress(b"FLASER 1 1 0 0 0\n" * 50)[:-12], "truncated gzip"),
        ("none.log", b"ODOM 0 0 0\nPARAM robot_length 0.5\n", "no FLASER or ROBOTLASER1 lines"),
        ("bad.log", b"FLASER 3 1 2\n", r"line 1: malformed FLASER line"),
        ("nan.log", b"FLASER 1 1.0 nan 0 0 0 0 0 0 h 0\n", r"line 1: malformed FLASER"),
        ("theta.log", b"FLASER 1 1.0 0 0 inf 0 0 0 0 h 0\n", r"theta .* is not 3 finite"),
        (
            "step.clf",
            b"ROBOTLASER1 0 -1.5 3.1 1e308 81.9 0.01 0 3 2.0 2.0 3.0 0 "
            b"0 0 0 0 0 0 0 0 0 0 0 5 h 6\n",
            r"start angle -1\.5 and step 1e\+308 over 3 readings overflow",
        ),
        ("negative.log", b"FLASER 2 1.0 -2 0 0 0 0 0 0 0 h 0\n", "readings must be numbers >= 0"),
        ("a.ply", b"ply\nformat ascii 1.0\nelement vertex 1\n", "no 'ply' magic or no end_header"),
        (
            "f128.ply",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float128 x\n"
            b"end_header\n" + bytes(16),
            r"line 4: expected 'property TYPE NAME' with TYPE one of",
        ),
        (
            "noz.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
            b"end_header\n1 2\n",
            "no z vertex property",
        ),
        (
            "short.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            b"property float z\nend_header\n1 2 3\n4 5 6\n",
            "truncated: 3 points announced, 2 found",
        ),
        (
            "zero.ply",
            b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n",
            r"no vertices \(element vertex 0\)",
        ),
        ("nodata.pcd", b"VERSION 0.7\nFIELDS x y z\n", r"not a PCD file \(no DATA line\)"),
        (
            "typex.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE X F F\nPOINTS 1\nDATA ascii\n1 2 3\n",
            "field 'x' has TYPE X SIZE 4: expected F 4/8",
        ),
        (
            "zero.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 0\nDATA binary\n",
            r"no points \(POINTS 0\)",
        ),
        (
            "short.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 3\nDATA ascii\n1 2 3\n4 5 6\n",
            "truncated: 3 points announced, 2 found",
        ),
        (
            "row.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA ascii\n1 2 3\n4 5\n",
            r"line 7: expected 3 numbers per point, got '4 5'",
        ),
        (
            "viewpoint.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nVIEWPOINT 0 0\nPOINTS 1\nDATA ascii\n1 2 3\n",
            "VIEWPOINT needs 7 finite numbers",
        ),
        (
            "lzf.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary_compressed\n"
            + np.array([4, 12], "<u4").tobytes()
            + b"\xff\xff\xff\xff",
            "corrupt LZF data",
        ),
        (
            "huge.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary_compressed\n"
            + np.array([4, 4_000_000_000], "<u4").tobytes()
            + bytes(4),
            "compressed data of 4000000000 bytes announced, expected 1 points of 12 bytes",
        ),
        (
            "count.pcd",
            b"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 99999999999 1 1\nPOINTS 1\nDATA binary\n",
            "field 'x' has COUNT 99999999999, expected 1 to 4096",
        ),
        ("garbage.bin", bytes(range(7)) * 3, "21 bytes is not a whole number of points"),
        ("short.graph", b"\x02\x00\x00\x00\x05\x00", r"byte 4: truncated"),
    ],
)
def test_bad_files_are_named(tmp_path, input_files, name, data, message):
    path = tmp_path / name
    if name.endswith(".bin"):
        path = tmp_path / "sequence" / "velodyne" / "000000.bin"
    path.write_bytes(data)
    options = {"poses": tmp_path / "sequence" / "poses.txt"} if name.endswith(".bin") else {}
    fails(path, message, **options)


def test_tum_folders_name_the_missing_or_broken_image(input_files):
    folder, _ = input_files["tum"]
    (folder / "poses.txt").write_text("depth/1.png 1 2 3 0 0 0 1\n")
    fails(folder, r"depth/1\.png: no such file")
    (folder / "depth" / "1.png").write_bytes(b"GIF89a not a png")
    fails(folder, r"1\.png: not a depth image")
    png = (folder / "depth" / "0.png").read_bytes()
    (folder / "depth" / "1.png").write_bytes(png[:45] + b"\x00" * 4 + png[49:])
    fails(folder, r"1\.png: not a depth image")
    (folder / "poses.txt").write_text("depth/0.png 1 2 3 0 0 0\n")
    fails(folder, r"poses\.txt, line 1: expected 'depth/FILE tx ty tz qx qy qz qw'")
    (folder / "poses.txt").write_text("depth/0.png 1 2 3 0 0 0 0\n")
    fails(folder, r"poses\.txt, line 1: .* is no rotation")
    (folder / "poses.txt").unlink()
    with pytest.raises(FileReadError, match=r"depth frames: tum: depth\.txt and groundtruth"):
        read_scans(folder)


def test_missing_inputs_and_folders_are_named(tmp_path, input_files):
    fails(tmp_path / "missing.ply", "no such file or folder")
    path, _ = input_files["000000.bin"]
    with pytest.raises(FileReadError, match=r"nowhere\.txt: no such file"):
        read_scans(path, poses=tmp_path / "nowhere.txt")
    (tmp_path / "folder.ply").mkdir()
    fails(tmp_path / "folder.ply", "a folder of scans is a KITTI sequence .* or depth frames")
    fails(tmp_path / "folder.ply", "is a folder; ply scans are files", format="ply")
    with pytest.raises(FileReadError, match=r"unknown extension '\.abc'"):
        read_scans(tmp_path / "a.abc")


def test_options_that_would_be_ignored_are_errors(input_files, tmp_path):
    poses = tmp_path / "poses.txt"
    poses.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n")
    for name in ("a.graph", "a.log", "tum"):
        path, _ = input_files[name]
        with pytest.raises(InputError, match="hold each scan's sensor pose: origin would be"):
            read_scans(path, origin=[0, 0, 0])
        with pytest.raises(InputError, match="poses would be ignored"):
            read_scans(path, poses=poses)
    path, _ = input_files["a.xyz"]
    with pytest.raises(InputError, match="give an origin or poses, not both"):
        read_scans(path, origin=[0, 0, 0], poses=poses)
    with pytest.raises(InputError, match="calib is for KITTI scans, not xyz files"):
        read_scans(path, calib="identity")
    with pytest.raises(InputError, match=re.escape("origin must be 3 finite numbers")):
        read_scans(path, origin=[0, np.nan, 0])


def test_broken_grid_and_array_files_are_named(tmp_path):
    from ehm.io.grid_file import load_grid
    from ehm.io.points import read_points

    np.savez_compressed(tmp_path / "g.npz", scores=np.zeros((40, 40)), intercept=0.0)
    data = bytearray((tmp_path / "g.npz").read_bytes())
    data[60:64] = b"\xff\xff\xff\xff"  # inside the first member's compressed bytes
    (tmp_path / "broken.npz").write_bytes(bytes(data))
    with pytest.raises(FileReadError, match=r"broken\.npz: not an ehm grid file"):
        load_grid(tmp_path / "broken.npz")
    with pytest.raises(FileReadError, match=r"g\.npz: not an ehm grid file \(no origin"):
        load_grid(tmp_path / "g.npz")
    (tmp_path / "q.npy").write_bytes(b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', #shape")
    with pytest.raises(FileReadError, match=r"q\.npy: not a NumPy array file"):
        read_points(tmp_path / "q.npy", 3)


def test_broken_distance_files_are_named(tmp_path):
    from ehm.io.distance_file import DistanceGrid, load_distance_grid, save_distance_grid

    field = DistanceGrid(np.zeros(2), 0.1, np.ones((4, 3)), np.zeros((4, 3, 2)), 0.5, False)
    save_distance_grid(field, tmp_path / "field.npz")
    read = load_distance_grid(tmp_path / "field.npz")
    np.testing.assert_array_equal(read.distance, field.distance)
    assert (read.resolution, read.level, read.unknown_is_occupied) == (0.1, 0.5, False)
    np.savez_compressed(tmp_path / "g.npz", scores=np.zeros((4, 3)), intercept=0.0)
    with pytest.raises(FileReadError, match=r"g\.npz: not an ehm distance file \(no distance"):
        load_distance_grid(tmp_path / "g.npz")
    arrays = dict(np.load(tmp_path / "field.npz"))
    np.savez_compressed(tmp_path / "bent.npz", **(arrays | {"gradient": np.zeros((4, 3, 3))}))
    with pytest.raises(FileReadError, match="shapes that do not agree"):
        load_distance_grid(tmp_path / "bent.npz")


def test_every_file_error_is_an_ehm_error_and_a_value_error():
    error = FileReadError("a.pcd", "truncated", "byte 12")
    assert isinstance(error, EhmError) and isinstance(error, ValueError)
    assert str(error) == "a.pcd, byte 12: truncated" and error.path == "a.pcd"
