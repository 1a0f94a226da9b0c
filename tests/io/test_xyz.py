"""Text point clouds."""

import bz2

import numpy as np

from ehm.io.xyz import read_xyz


def test_xyz_text_and_bz2(tmp_path, cloud):
    text = "\n".join(" ".join(f"{v:.9g}" for v in p) for p in cloud)
    (tmp_path / "a.xyz").write_text(text)
    (tmp_path / "a.dat.bz2").write_bytes(bz2.compress(text.encode()))
    np.testing.assert_allclose(read_xyz(tmp_path / "a.xyz"), cloud, rtol=1e-7)
    np.testing.assert_allclose(read_xyz(tmp_path / "a.dat.bz2"), cloud, rtol=1e-7)


def test_a_table_of_many_columns_is_refused_as_no_point_file(tmp_path):
    import pytest

    from ehm.errors import FileReadError

    (tmp_path / "a.txt").write_text("# x y z intensity r g b\n1 2 3 0.5 10 20 30\n")
    np.testing.assert_array_equal(read_xyz(tmp_path / "a.txt"), [[1, 2, 3]])
    (tmp_path / "log.txt").write_text("# laser\n" + " ".join(["1.5"] * 707) + "\n")
    with pytest.raises(FileReadError, match=r"log\.txt, line 2: 707 columns, and a point is"):
        read_xyz(tmp_path / "log.txt")
