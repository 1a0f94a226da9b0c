"""BENCHMARKS.md, made from the results of the last run of each benchmark.

    python benchmarks/report.py

Each script in benchmarks/ leaves benchmarks/results/<script>.json when it ends well
(benchmarks/results_file.py). This writes one section per script, in the order of SECTIONS,
under its title there: what it measures (its docstring's first paragraph), then between
snippet markers named after the script (the documentation's benchmarks page includes them)
the command, date and machine of its last run and what that run printed. Scripts without
results are listed at the end with the command that makes them.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

from results_file import RESULTS

BENCHMARKS = Path(__file__).parent
OUTPUT = BENCHMARKS.parent / "BENCHMARKS.md"
# The sections, most read first: against the peers, then accuracy, speed, queries, outputs,
# robustness, start-up.
SECTIONS = {
    "peers": "Against OctoMap, wavemap and DUFOMap",
    "nav2_maps": "2D maps for nav2",
    "calibration": "Calibrated occupancy: held-out rays read raw and calibrated",
    "changing_scene": "Changing scenes",
    "paper_evaluation": "The paper's evaluation (Sec. 4)",
    "online_mapping": "Online mapping: scan by scan, one batch and OctoMap",
    "outdoor_ranges": "Outdoor scenes near surfaces, by range",
    "stray_returns": "Stray returns in open space",
    "octomap_scan": "OctoMap's sample scan",
    "virtual_room": "The virtual room, against its exact occupancy",
    "uncertainty": "Uncertainty (return_std)",
    "kernel_selection": "Kernel selection and hierarchy (Sec. 3.1, 3.2, 3.4)",
    "feature_search": "Which kernels make a point's features: 'nearest' and 'support'",
    "scan_times": "Time per scan as the map grows",
    "integrate_times": "One integrate, stage by stage",
    "grids": "Occupancy grids and meshes (Sec. 3.5)",
    "raycast": "Ray casting against OctoMap's castRay",
    "point_queries": "Point queries against OctoMap's getLabels",
    "distance": "Distances to obstacles",
    "planner_loop": "A planner in the loop",
    "outdoor_outputs": "Outputs of an outdoor LiDAR sweep",
    "tiles": "Tiled maps",
    "corpus": "Users' own recordings",
    "bag_stream": "Streaming a ROS 2 bag",
    "pcd_readers": "PCD readers",
    "soak": "Long runs",
    "viewer": "The viewer",
    "startup": "Start-up, install and first calls",
}
INTRODUCTION = """# Benchmarks

Made by `python benchmarks/report.py` from `benchmarks/results/`: the last run of each script
in `benchmarks/`, what it measures, its command, date and machine. Speed is compared with the
peers as ratios measured in one process on the same data at the same resolution, compiled code
warmed: absolute times drift on a shared machine, the ratios less. Why the defaults are what
they are: docs/reference/defaults.md.
"""


def purpose(script: Path) -> str:
    """What a script measures: its docstring's first paragraph (the title line), the rest
    being for whoever runs it."""
    docstring = ast.get_docstring(ast.parse(script.read_text())) or ""
    return docstring.strip().split("\n\n")[0]


def section(name: str, record: dict) -> str:
    """One script's section of BENCHMARKS.md: its title, what it measures, then between
    snippet markers named after it (which the docs' benchmarks page includes) its command and
    what it printed."""
    title, measures = SECTIONS[name], purpose(BENCHMARKS / f"{name}.py")
    printed = "\n".join(
        "#" + line if line.startswith("## ") else line
        for line in record["markdown"].strip().splitlines()
    )
    parts = [
        f"## {title}",
        measures,
        f"<!-- --8<-- [start:{name}] -->",
        f"Command: `{record['command']}`, {record['date']}, {record['machine']}.",
        printed,
        f"<!-- --8<-- [end:{name}] -->",
    ]
    return "\n\n".join(p for p in parts if p) + "\n"


def report() -> str:
    """The text of BENCHMARKS.md."""
    sections, missing = [INTRODUCTION], []
    for name in SECTIONS:
        path = RESULTS / f"{name}.json"
        if path.exists():
            sections.append(section(name, json.loads(path.read_text())))
        else:
            missing.append(f"- {SECTIONS[name]}: `python benchmarks/{name}.py`")
    if missing:
        sections.append("## Not run since results were kept\n\n" + "\n".join(missing) + "\n")
    return "\n".join(sections)


def main() -> None:
    unlisted = {p.stem for p in BENCHMARKS.glob("*.py")} - set(SECTIONS)
    unlisted -= {"common", "results_file", "report", "corpus_sources"}
    if unlisted:
        raise SystemExit(f"benchmarks without a section in report.SECTIONS: {sorted(unlisted)}")
    OUTPUT.write_text(report())
    print(f"wrote {OUTPUT}")


if __name__ == "__main__":
    main()
