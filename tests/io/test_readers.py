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
