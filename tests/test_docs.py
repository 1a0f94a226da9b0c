"""The documentation cannot rot: the site builds with --strict, and every example in it runs.

Each page's ```python blocks run in order in one namespace, and each `$ ehm ...` line of its
```console blocks runs as a command (what follows a command up to the next is its expected
output when it is an `error:` line: the command must fail with exactly that message), in a
folder of small files of every format the guides use (`workspace`). Blocks marked ```text are
shown, not run.
"""

import importlib
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ehm.cli import app
from ehm.core.sensor.frames import matrix_to_quaternion
from ehm.eval.datasets.simulated import (
    lidar_directions,
    simulate_scan,
    virtual_room_scene,
)

ROOT = Path(__file__).resolve().parents[1]
PAGES = [*sorted((ROOT / "docs").rglob("*.md")), ROOT / "README.md"]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.MULTILINE | re.DOTALL)


@dataclass(frozen=True)
class Block:
    language: str
    code: str
    line: int


def code_blocks(text: str) -> list[Block]:
    """The fenced blocks of a Markdown text, in order, with the line each starts on."""
    return [
        Block(m.group(1), m.group(2), text.count("\n", 0, m.start()) + 1)
        for m in FENCE.finditer(text)
    ]


def console_commands(code: str) -> list[tuple[list[str], list[str]]]:
    """The `$ ehm ...` commands of a console block (a line ending in a backslash goes on),
    each with the lines shown after it."""
    commands: list[tuple[list[str], list[str]]] = []
    lines = iter(code.splitlines())
    for line in lines:
        if line.startswith("$ "):
            text = line[2:]
            while text.endswith("\\"):
                text = text[:-1] + next(lines)
            commands.append((shlex.split(text, comments=True), []))
        elif commands:
            commands[-1][1].append(line)
    return commands


def test_code_blocks_and_commands_are_found():
    text = "a\n```python\nx = 1\n```\n\n```console\n$ ehm info a.ehm \\\n  --x  # c\nout\n```\n"
    blocks = code_blocks(text)
    assert [(b.language, b.line) for b in blocks] == [("python", 2), ("console", 6)]
    assert console_commands(blocks[1].code) == [(["ehm", "info", "a.ehm", "--x"], ["out"])]


@pytest.fixture(scope="session")
def workspace(tmp_path_factory, plan_log):
    """Small files of the formats the guides read: a CARMEN log (`floor.log`), a ROS 1 bag of
    three LiDAR sweeps placed by /tf (`room.bag`), TUM depth frames (`tum_fr2/`), and a KITTI
    sequence (`kitti/sequences/00` with `kitti/poses/00.txt`)."""
    folder = tmp_path_factory.mktemp("docs")
    shutil.copy(plan_log, folder / "floor.log")
    scene, rng = virtual_room_scene(), np.random.default_rng(0)
    origins = np.array([[-1.0, 0.0, 1.2], [0.0, 0.0, 1.2], [1.0, 0.2, 1.2]])
    sweeps = [
        simulate_scan(scene, o, lidar_directions(32, 512, 30.0), 20.0, 0.01, rng) for o in origins
    ]
    _write_bag(folder / "room.bag", sweeps)
    _write_tum(folder / "tum_fr2", scene, origins)
    _write_kitti(folder / "kitti", sweeps)
    return folder


def _write_bag(path: Path, sweeps) -> None:
    """Sweeps in the frame `velodyne`, placed in `map` by /tf, one a second."""
    from ros_bags import SECOND, write_bag
    from rosbags.typesys import Stores

    messages = [("/tf_static", 0, lambda m: m.transform(0, "base_link", "velodyne", (0, 0, 0)))]
    for i, sweep in enumerate(sweeps):
        stamp, origin = (i + 1) * SECOND, tuple(sweep.origin)
        points = sweep.points_world[sweep.hit_mask] - sweep.origin
        messages += [
            ("/tf", stamp, lambda m, s=stamp, o=origin: m.transform(s, "map", "base_link", o)),
            ("/velodyne_points", stamp, lambda m, s=stamp, p=points: m.cloud(s, "velodyne", p)),
        ]
    write_bag(path, Stores.ROS1_NOETIC, messages)


def _write_tum(folder: Path, scene, origins) -> None:
    """640 x 480 depth frames looking along +x (the camera's z), in TUM's layout, through
    Freiburg 2's intrinsics (the folder's name names them); only the pixels the reader takes
    (every second row and column) are rendered, the rest read 0, no depth."""
    from PIL import Image

    from ehm.io.depth import PIXEL_STRIDE
    from ehm.io.tum import FREIBURG_CAMERAS

    fx, fy, cx, cy = FREIBURG_CAMERAS[2].intrinsics
    stride = PIXEL_STRIDE
    (folder / "depth").mkdir(parents=True)
    v, u = np.mgrid[0:480:stride, 0:640:stride]
    rays_camera = np.column_stack([(u.ravel() - cx) / fx, (v.ravel() - cy) / fy, np.ones(u.size)])
    # Camera: x right, y down, z forward -> world: x forward, y left, z up.
    R_world_camera = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    directions = rays_camera @ R_world_camera.T
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    w, x, y, z = matrix_to_quaternion(R_world_camera)
    q = (x, y, z, w)  # TUM's order
    lines = []
    for i, origin in enumerate(origins):
        ranges = scene.raycast(origin, directions)
        depth = ranges * (directions @ R_world_camera[:, 2])
        image = np.zeros((480, 640), dtype=np.uint16)
        image[::stride, ::stride] = np.where(ranges < 8.0, np.round(depth * 5000), 0).reshape(
            v.shape
        )
        Image.fromarray(image).save(folder / "depth" / f"{i}.png")
        lines.append(f"depth/{i}.png {' '.join(map(str, origin))} {' '.join(map(str, q))}")
    (folder / "poses.txt").write_text("\n".join(lines) + "\n")


def _write_kitti(folder: Path, sweeps) -> None:
    """The odometry layout, with poses of the Velodyne itself (calib.txt's Tr the identity)."""
    sequence = folder / "sequences" / "00"
    (sequence / "velodyne").mkdir(parents=True)
    (folder / "poses").mkdir()
    poses = []
    for i, sweep in enumerate(sweeps):
        points = sweep.points_world[sweep.hit_mask] - sweep.origin
        raw = np.column_stack([points, np.ones(len(points))]).astype("<f4")
        raw.tofile(sequence / "velodyne" / f"{i:06d}.bin")
        pose = np.hstack([np.eye(3), sweep.origin[:, None]])
        poses.append(" ".join(f"{x:g}" for x in pose.ravel()))
    (sequence / "calib.txt").write_text("Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n")
    (sequence / "times.txt").write_text("".join(f"{0.1 * i:f}\n" for i in range(len(sweeps))))
    (folder / "poses" / "00.txt").write_text("\n".join(poses) + "\n")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_example_runs(page, workspace, tmp_path, monkeypatch):
    shutil.copytree(workspace, tmp_path, dirs_exist_ok=True)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__main__"}
    for block in code_blocks(page.read_text()):
        where = f"{page.relative_to(ROOT)}:{block.line}"
        if block.language == "python":
            exec(compile(block.code, where, "exec"), namespace)
        elif block.language == "console":
            for args, shown in console_commands(block.code):
                _check_command(args, shown, where)


def _check_command(args: list[str], shown: list[str], where: str) -> None:
    """Run `ehm ...` in this process: it succeeds, or fails with the error line shown."""
    assert args[0] == "ehm", f"{where}: only ehm commands run in console blocks"
    result = CliRunner().invoke(app, args[1:])
    errors = [line for line in shown if line.startswith("error:")]
    if errors:
        assert result.exit_code == 2, f"{where}: {args} succeeded, expected {errors[0]}"
        assert errors[0] in result.output.splitlines(), f"{where}: {result.output}"
    else:
        assert result.exit_code == 0, f"{where}: {shlex.join(args)}\n{result.output}"


def test_the_api_reference_covers_every_public_name():
    """Every name of ehm.__all__, ehm.io.readers, ehm.pipeline and ehm.tiles has a `:::`
    entry of its own in the API page, or is a listed member of a module's entry."""
    page = (ROOT / "docs" / "reference" / "api.md").read_text()
    documented = set()
    for entry in re.finditer(r"^::: ([\w.]+)\n((?:    .*\n)*)", page, re.MULTILINE):
        target, options = entry.group(1), entry.group(2)
        members = re.search(r"members: \[(.*)\]", options)
        if members:
            module = importlib.import_module(target)
            documented |= {id(getattr(module, n.strip())) for n in members.group(1).split(",")}
        else:
            module_name, _, name = target.rpartition(".")
            documented.add(id(getattr(importlib.import_module(module_name), name)))
    missing = []
    for module_name in ("ehm", "ehm.io.readers", "ehm.pipeline", "ehm.tiles"):
        module = importlib.import_module(module_name)
        names = getattr(module, "__all__", None) or [
            n
            for n, value in vars(module).items()
            if not n.startswith("_") and getattr(value, "__module__", None) == module_name
        ]
        missing += [f"{module_name}.{n}" for n in names if id(getattr(module, n)) not in documented]
    assert not missing, f"not in docs/reference/api.md: {missing}"


def test_the_site_builds_strictly(tmp_path):
    mkdocs = Path(sys.executable).with_name("mkdocs")
    result = subprocess.run(
        [str(mkdocs), "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert result.returncode == 0, result.stderr
    site = tmp_path / "site"
    assert (site / "reference" / "cli.html").exists()
    # Opened from disk, a link must name a file: a folder would list its files. (404.html is
    # a server's page, linked from the site's root.)
    for page in set(site.rglob("*.html")) - {site / "404.html"}:
        for target in re.findall(r'href="(?![a-z]+:)([^"#?]+)', page.read_text()):
            linked = (page.parent / target).resolve()
            assert linked.is_file(), f"{page.relative_to(site)} links to {target}"
    assert not list(site.rglob("*.py")), "the build's hooks are not part of the site"
