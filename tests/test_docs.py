"""The documentation cannot rot: the site builds with --strict, and every example in it runs.

Each page's ```python blocks run in order in one namespace, and each `$ ehm ...` line of its
```console blocks runs as a command (what follows a command up to the next is its expected
output when it is an `error:` line: the command must fail with exactly that message), in a
copy of the folder `ehm demo --data` writes, the recordings the guides use (`workspace`).
Blocks marked ```text are shown, not run.
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

import pytest
from typer.testing import CliRunner

from ehm.cli import app

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
def workspace(tmp_path_factory):
    """The folder `ehm demo --data` writes, as a user makes it before following a guide."""
    folder = tmp_path_factory.mktemp("docs") / "ehm_guides"
    result = CliRunner().invoke(app, ["demo", "--data", str(folder)])
    assert result.exit_code == 0, result.output
    return folder


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
    entry of its own in the API page, or is a listed member of a module's entry; a class
    whose entry lists its members (in the order a user meets them) lists every public one."""
    page = (ROOT / "docs" / "reference" / "api.md").read_text()
    documented = set()
    missing = []
    for entry in re.finditer(r"^::: ([\w.]+)\n((?:    .*\n)*)", page, re.MULTILINE):
        target, options = entry.group(1), entry.group(2)
        found = re.search(r"members: \[(.*)\]", options)
        members = [] if found is None else [n.strip() for n in found.group(1).split(",")]
        module_name, _, name = target.rpartition(".")
        if members and name[0].islower():  # a module's listed members
            module = importlib.import_module(target)
            documented |= {id(getattr(module, n)) for n in members}
            continue
        documented.add(id(getattr(importlib.import_module(module_name), name)))
        if members:  # a class's listed members
            public = [n for n in vars(getattr(importlib.import_module(module_name), name))
                      if not n.startswith("_")]  # fmt: skip
            missing += [f"{target}.{n}" for n in public if n not in members]
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
