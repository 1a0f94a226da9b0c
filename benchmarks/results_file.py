"""What a benchmark run leaves: benchmarks/results/<script>.json, written when the script ends
well, with the command, the date, the machine and what the script printed (Markdown: its
headings, tables and lines), its tables also as columns and rows. BENCHMARKS.md is made from
these files (benchmarks/report.py); a run that fails leaves the last good file in place."""

from __future__ import annotations

import io
import json
import os
import platform
import sys
from collections.abc import Callable
from datetime import date
from pathlib import Path

RESULTS = Path(__file__).parent / "results"


class _Tee(io.TextIOBase):
    """Writes to the terminal and keeps a copy."""

    def __init__(self, terminal) -> None:
        self.terminal = terminal
        self.kept = io.StringIO()

    def write(self, text: str) -> int:
        self.kept.write(text)
        return self.terminal.write(text)

    def flush(self) -> None:
        self.terminal.flush()


def run_recorded(main: Callable[[], None], script: str) -> None:
    """Run a benchmark's `main`, and when it ends without an error write what it printed to
    RESULTS/<script's stem>.json."""
    tee = _Tee(sys.stdout)
    sys.stdout = tee
    try:
        main()
    finally:
        sys.stdout = tee.terminal
    markdown = "\n".join(line for line in tee.kept.getvalue().splitlines() if not _noise(line))
    record = {
        "script": Path(script).name,
        "command": " ".join(["python", f"benchmarks/{Path(script).name}", *sys.argv[1:]]),
        "date": date.today().isoformat(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}",
        "markdown": markdown,
        "tables": markdown_tables(markdown),
    }
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"{Path(script).stem}.json"
    path.write_text(json.dumps(record, indent=1) + "\n")


def _noise(line: str) -> bool:
    """Whether a printed line is a library's, not the benchmark's: viser's server banner (a
    box drawn in box-drawing characters) and its goodbye."""
    return line.startswith("(viser)") or any("\u2500" <= c <= "\u257f" for c in line[:1])


def markdown_tables(text: str) -> list[dict]:
    """The Markdown tables of `text`, each {"columns": [...], "rows": [[...], ...]}."""
    tables, block = [], []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            block.append([cell.strip() for cell in line.strip().strip("|").split("|")])
            continue
        if len(block) >= 2:
            tables.append({"columns": block[0], "rows": block[2:]})
        block = []
    return tables
