"""Choosing the reader of an input."""

import pytest

from ehm.io.readers import guess_format, read_scans


def test_format_guess_and_errors(tmp_path):
    assert guess_format("a.PCD") == "pcd"
    assert guess_format("scan.dat.bz2") == "xyz"
    with pytest.raises(ValueError, match=r"unknown extension '\.abc'"):
        guess_format("a.abc")
    with pytest.raises(ValueError, match="no such file"):
        read_scans(tmp_path / "missing.ply")


def test_scans_stream_one_at_a_time_after_the_checks(input_files, tmp_path):
    from ehm.errors import FileReadError, InputError
    from ehm.io.readers import scan_stream

    path, options = input_files["000000.bin"]
    broken = path.with_name("000001.bin")
    broken.write_bytes(bytes(20))
    poses = options["poses"]
    poses.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n" * 2)
    stream = scan_stream([path, broken], poses=poses)  # checks pass; nothing read yet
    assert len(next(stream)) == 50
    with pytest.raises(FileReadError, match=r"000001\.bin: 20 bytes"):
        next(stream)
    path.with_name("000007.bin").write_bytes(bytes(20))
    with pytest.raises(FileReadError, match=r"poses\.txt: 2 poses: none for frame 7"):
        scan_stream([path, path.with_name("000007.bin")], poses=poses)  # before any read
    xyz, _ = input_files["a.xyz"]
    picked = list(scan_stream([xyz] * 7, every=3, limit=2))
    assert len(picked) == 2
    with pytest.raises(InputError, match="limit must be an integer >= 0"):
        scan_stream(xyz, limit=-1)
