"""The browser viewer's costs: opening a map, re-meshing, and mapping with the live view open.

    python benchmarks/viewer.py

Open: `MapViewer` on OctoMap's sample scan's map at 0.1 m (grid with the std, mesh, scene).
Re-mesh: the level slider moved to 0.7, then back to 0.5. Live: the TUM sequence mapped with
the defaults without and with `LiveView` (refreshing every 2 s), one run each, same process.
Then the docs' picture of the viewer: the virtual room's map, cut above 2.2 m, in headless
Chromium, into docs/images/viewer.png.
"""

from __future__ import annotations

import socket
import sys
import time
from pathlib import Path

import numpy as np
from common import heading, markdown_table
from PIL import Image
from results_file import run_recorded

import ehm
from ehm.eval.datasets import DataMissingError, load_dataset, virtual_room
from ehm.pipeline import MappingPipeline
from ehm.viz.viewer import LiveView, MapViewer, browser_screenshot


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def main() -> None:
    rows = []
    try:
        sample = ehm.HilbertMap().fit(load_dataset("octomap_scan"))
        start = time.perf_counter()
        viewer = MapViewer(sample, resolution=0.1, port=free_port())
        rows.append(["open the sample scan's map at 0.1 m", f"{time.perf_counter() - start:.2f}"])
        for level in (0.7, 0.5):
            start = time.perf_counter()
            viewer.level.value = level
            rows.append([f"re-mesh at level {level}", f"{time.perf_counter() - start:.2f}"])
        viewer.server.stop()
    except DataMissingError as missing:
        print(f"skipped the sample scan: {missing}")
    try:
        frames = load_dataset("tum_fr2_pioneer_slam2")
        MappingPipeline(frames[:1], ehm.HilbertMap()).run()  # compile
        plain = MappingPipeline(frames, ehm.HilbertMap()).run().seconds
        live = LiveView(port=free_port())
        viewed = MappingPipeline(frames, ehm.HilbertMap(), observers=[live]).run().seconds
        live.server.stop()
        rows.append([f"map TUM ({len(frames)} frames) alone", f"{plain:.2f}"])
        rows.append([f"map TUM with the live view ({live.refreshes} refreshes)", f"{viewed:.2f}"])
        rows.append(["speed with the view / alone", f"{plain / viewed:.2f}"])
    except DataMissingError as missing:
        print(f"skipped TUM: {missing}")
    print(heading("Viewer", "seconds"))
    print(markdown_table(["step", "seconds"], rows))
    picture = Path(__file__).resolve().parents[1] / "docs" / "images" / "viewer.png"
    take_picture(ehm.HilbertMap().fit(virtual_room().scans), picture)
    print(f"wrote {picture}", file=sys.stderr)


def take_picture(hilbert_map: ehm.HilbertMap, path: Path, attempts: int = 5) -> None:
    """A screenshot of the map in headless Chromium, 1200 x 800 pixels, as the viewer opens
    (cut a metre above the sensor), taken again while the mesh still fades in."""
    viewer = MapViewer(hilbert_map, resolution=0.1, port=free_port())
    try:
        for _ in range(attempts):
            browser_screenshot(viewer.url, path)
            image = np.asarray(Image.open(path).convert("RGB")).astype(int)
            centre = image[300:500, 500:700]
            if np.mean(centre.max(axis=2) - centre.min(axis=2) > 60) > 0.5:
                return
    finally:
        viewer.server.stop()


if __name__ == "__main__":
    run_recorded(main, __file__)
