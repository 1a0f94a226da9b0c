"""The package's layers: imports only go down, with no cycles, and `import ehm` stays light."""

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

import ehm
import ehm.hilbert_map
import ehm.maps

PACKAGE = Path(ehm.__file__).parent

# From the bottom up: a module may import its own layer and the layers below it.
LAYERS = (
    "ehm.errors",
    "ehm.config",
    "ehm.core",
    "ehm.grid",
    "ehm.io",
    "ehm.map_queries",
    "ehm.hilbert_map",
    "ehm.pipeline",
    "ehm.tiles",
    "ehm.maps",
    "ehm.changes",
    "ehm.viz",
    "ehm.warm",
    "ehm.eval",
    "ehm.cli",
    "ehm",
)


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(path): path for path in sorted(PACKAGE.rglob("*.py"))}


def imported_modules(name: str) -> set[str]:
    """The ehm modules `name` imports anywhere: at the top, inside functions, for type
    checking only. `from a import b` counts as importing a.b when that is a module, else a."""
    found = set()
    package = name if MODULES[name].name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(MODULES[name].read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base)
    return {m for m in found if m == "ehm" or m.startswith("ehm.")}


GRAPH = {name: imported_modules(name) for name in MODULES}


def layer(name: str) -> int:
    """Index in LAYERS of a module: the package root is the top, every other module belongs
    to the layer its name starts with."""
    if name == "ehm":
        return len(LAYERS) - 1
    return next(i for i, top in enumerate(LAYERS) if name == top or name.startswith(top + "."))


def test_every_import_names_a_module_of_the_package():
    for name, imports in GRAPH.items():
        assert imports <= set(MODULES), f"{name} imports {imports - set(MODULES)}"


def test_imports_only_go_down_the_layers():
    upward = [
        f"{name} ({LAYERS[layer(name)]}) imports {target} ({LAYERS[layer(target)]})"
        for name, imports in GRAPH.items()
        for target in imports
        if layer(target) > layer(name)
    ]
    assert upward == []


# ehm.core's layers, from the bottom up: a module of one may import its own layer and those
# below it (the modules at core's top level, snapshot, state and timing, sit above them all).
CORE_LAYERS = (
    ("primitives",),
    ("sensor",),
    ("model",),
    ("search",),
    ("observations",),
    ("clustering", "weights"),
    ("queries",),
)


def core_layer(name: str) -> int | None:
    """The index in CORE_LAYERS of an ehm.core module's subpackage; None outside them."""
    parts = name.split(".")
    if parts[:2] != ["ehm", "core"] or len(parts) < 4:
        return None
    return next(i for i, names in enumerate(CORE_LAYERS) if parts[2] in names)


def test_the_core_subpackages_import_only_down_their_layers():
    upward = [
        f"{name} imports {target}"
        for name, imports in GRAPH.items()
        for target in imports
        if core_layer(name) is not None
        and core_layer(target) is not None
        and core_layer(target) > core_layer(name)
    ]
    assert upward == []
    subpackages = {p.name for p in (PACKAGE / "core").iterdir() if (p / "__init__.py").exists()}
    assert subpackages == {name for names in CORE_LAYERS for name in names}


def test_there_are_no_import_cycles():
    state: dict[str, str] = {}

    def visit(name: str, path: list[str]) -> None:
        state[name] = "open"
        for target in sorted(GRAPH[name]):
            assert state.get(target) != "open", " -> ".join([*path, name, target])
            if target not in state:
                visit(target, [*path, name])
        state[name] = "done"

    for name in MODULES:
        if name not in state:
            visit(name, [])


def test_the_checker_sees_imports_inside_functions_and_for_type_checking():
    assert "ehm.eval.runner" in GRAPH["ehm"]  # for type checking
    assert "ehm.eval.baselines.octree" in GRAPH["ehm.eval.baselines"]  # inside factories
    assert "ehm.hilbert_map" in GRAPH["ehm.cli.mapping"]  # inside commands


def loaded_after(statement: str) -> set[str]:
    """Modules a fresh interpreter has loaded after running `statement`."""
    script = f"import sys; {statement}; print('\\n'.join(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    )
    return set(result.stdout.split())


def test_importing_ehm_shortens_openmps_spinning_unless_the_environment_sets_it():
    script = "import os, ehm; print(os.environ['GOMP_SPINCOUNT'])"
    environment = {k: v for k, v in os.environ.items() if k != "GOMP_SPINCOUNT"}

    def spin_count(env: dict[str, str]) -> str:
        run = subprocess.run(
            [sys.executable, "-c", script], capture_output=True, text=True, check=True, env=env
        )
        return run.stdout.strip()

    assert spin_count(environment) == "3000"
    assert spin_count({**environment, "GOMP_SPINCOUNT": "77"}) == "77"


def test_the_public_api_is_loaded_on_first_use():
    assert loaded_after("import ehm") & {"ehm.hilbert_map", "numpy"} == set()
    for name in ehm.__all__:
        assert getattr(ehm, name).__name__ == name
        assert name in dir(ehm)
    assert ehm.load is ehm.maps.load
    with pytest.raises(AttributeError, match="module 'ehm' has no attribute 'Map'"):
        ehm.Map  # noqa: B018


def test_the_library_loads_neither_evaluation_nor_pictures_nor_readers():
    loaded = loaded_after("import ehm; ehm.HilbertMap().integrate; ehm.load")
    assert "ehm.hilbert_map" in loaded
    heavy = ("ehm.eval", "ehm.viz", "ehm.pipeline", "ehm.cli", "ehm.io.readers", "ehm.io.ply")
    heavy += ("matplotlib", "PIL", "typer", "rich", "octomap", "dask", "distributed")
    assert sorted(m for m in loaded if m.startswith(heavy)) == []


def test_the_command_line_imports_no_numerics_until_a_command_runs():
    loaded = loaded_after("import ehm.cli")
    assert sorted(m for m in loaded if m.startswith(("numpy", "numba", "scipy", "ehm"))) == [
        "ehm",
        "ehm.cli",
        "ehm.cli.app",
        "ehm.cli.evaluation",
        "ehm.cli.inspection",
        "ehm.cli.mapping",
        "ehm.cli.outputs",
        "ehm.errors",
    ]


def test_only_the_pipeline_loops_over_scans():
    """HilbertMap.integrate_scan is called by the pipeline (and by HilbertMap.integrate), so the
    loop that reads, learns and times scans is written once; a tiled map's tiles learn the
    part of each scan that crosses them in one function, ehm.tiles.build.learn_into_tiles
    (called by TiledMap.integrate_scan, itself called by TiledMap.integrate)."""
    callers = set()
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr == "integrate_scan":
                callers.add(name)
    assert callers == {"ehm.pipeline", "ehm.hilbert_map", "ehm.tiles.build", "ehm.tiles.tiled_map"}


def test_only_the_command_line_imports_the_viewer():
    importers = sorted(name for name, imports in GRAPH.items() if "ehm.viz.viewer" in imports)
    assert importers == ["ehm.cli.inspection", "ehm.cli.mapping"]


def test_the_core_tests_mirror_the_core_modules():
    tests = Path(__file__).parent / "core"
    unmatched = [
        str(test.relative_to(tests))
        for test in tests.rglob("test_*.py")
        if not (PACKAGE / "core" / test.parent.relative_to(tests) / f"{test.stem[5:]}.py").exists()
    ]
    assert unmatched == []
