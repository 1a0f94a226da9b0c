"""The viewer in a real browser: Debian's headless Chromium (`make test` installs it) opens the
page, and its screenshot must show the map."""

import shutil
import socket
import threading
import time

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("viser")
from ehm.viz.viewer import MapViewer, browser_screenshot

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_the_page_shows_the_map(room_map, tmp_path):
    assert CHROMIUM, "chromium is missing: `make test` installs Debian's chromium package"
    viewer = MapViewer(room_map, resolution=0.1, port=free_port())
    connected = threading.Event()
    viewer.server.on_client_connect(lambda client: connected.set())
    shot = tmp_path / "viewer.png"
    try:
        # Chromium's virtual time can run out before the map reaches the page over its
        # websocket when the machine is busy, or catch the mesh while it fades in (a quarter
        # of the pictures on a quiet machine, more after a long test run): the picture is
        # taken again then, a few seconds apart, up to eight times.
        for attempt in range(8):
            time.sleep(min(3.0 * attempt, 6.0))
            browser_screenshot(viewer.url, shot)
            image = np.asarray(Image.open(shot).convert("RGB")).astype(int)
            colours, coloured_centre = picture_measures(image)
            if colours > 2000 and coloured_centre > 0.5:
                break
    finally:
        viewer.server.stop()
    assert connected.is_set()  # the page reached the server
    assert image.shape == (800, 1200, 3)
    assert colours > 2000  # a picture, not a blank page
    # Where the camera looks (the map's centre, seen through the cut above the sensor), the
    # surface: coloured pixels, not the white background, the grey floor grid or a faded mesh.
    assert coloured_centre > 0.5


def picture_measures(image: np.ndarray) -> tuple[int, float]:
    """The screenshot's number of distinct colours, and the fraction of strongly coloured
    pixels in its centre."""
    colours = len(np.unique(image.reshape(-1, 3), axis=0))
    centre = image[300:500, 500:700]
    saturation = centre.max(axis=2) - centre.min(axis=2)
    return colours, float(np.mean(saturation > 60))
