"""Choosing the reader of an input."""

import numpy as np
import pytest

from ehm.io.readers import guess_format, read_scans


def test_format_guess_and_errors(tmp_path):
    assert guess_format("a.PCD") == "pcd"
    assert guess_format("scan.dat.bz2") == "xyz"
    assert guess_format("scan.bz2") == "xyz"
    assert guess_format("intel.log.gz") == "carmen"
    assert guess_format("cloud.PCD.GZ") == "pcd"
    with pytest.raises(ValueError, match="a compressed bag is not read; decompress it first"):
        guess_format("old.bag.gz")
    with pytest.raises(ValueError, match="compressed packet capture is not read; decompress"):
        guess_format("drive.pcap.gz")
    with pytest.raises(ValueError, match=r"unknown extension '\.abc'"):
        guess_format("a.abc.gz")
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


def test_scan_files_read_by_index_what_iterating_reads(tmp_path, plan_log):
    import pickle

    import numpy as np

    from ehm.io.readers import ScanFiles

    paths = []
    for i in range(5):
        paths.append(tmp_path / f"s{i}.xyz")
        np.savetxt(paths[-1], np.random.default_rng(i).normal(size=(30, 3)))
    files = ScanFiles(paths, origin=[0.0, 0.0, 1.0], every=2)
    log = ScanFiles(plan_log, limit=4)
    for source, count in ((files, 3), (log, None)):
        source = pickle.loads(pickle.dumps(source))  # as a cluster's workers get it
        everything = list(source)
        assert source.count() == count
        assert len(everything) == 3 if count else len(everything) == 4
        picked = list(source.read([2, 0]))
        assert [i for i, _ in picked] == [0, 2]
        for i, scan in picked:
            np.testing.assert_array_equal(scan.points_world, everything[i].points_world)
            np.testing.assert_array_equal(scan.origin, everything[i].origin)
        assert [i for i, _ in source.read()] == list(range(len(everything)))


def test_point_clouds_far_from_where_their_sensor_is_taken_to_stand_are_refused(tmp_path):
    from ehm.errors import FileReadError

    path = tmp_path / "utm.xyz"
    np.savetxt(path, np.array([[499_750.0, 4_200_300.0, 2160.0], [499_760.0, 4_200_310.0, 2161.0]]))
    with pytest.raises(FileReadError, match=r"utm\.xyz: its points lie 4230 km or more from"):
        read_scans(path)
    (scan,) = read_scans(path, origin=[499_755.0, 4_200_305.0, 2400.0])
    assert len(scan) == 2
