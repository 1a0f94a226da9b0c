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
