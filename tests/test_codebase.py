"""The package's shape (docs/ARCHITECTURE.md): imports run one way, modules and functions stay small, numpy
references stay in the test tree, and library code takes its configuration from the caller."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "ptam"
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 60

# Rank of each top-level part of ptam: a module may import its own part and parts of lower rank only. Parts
# of equal rank are peers and do not import each other (tracking and mapping share ``patch`` instead).
LAYERS = {
    "errors": 0,
    "resources": 0,
    "vocabulary": 0,
    "config": 1,
    "geometry": 2,
    "eval": 3,  # metrics: a leaf anything may use
    "camera": 3,
    "image": 4,
    "capture": 4,
    "map": 5,
    "patch": 6,
    "edgelet": 6,
    "tracking": 7,
    "mapping": 7,
    "synthetic": 7,
    "system": 8,
    "viz": 9,  # observers: nothing they observe imports them
    "ar": 9,
    "bench": 10,
    "commands": 11,
    "cli": 12,
    "__main__": 13,
}


def _modules():
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def _part(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _imports(path: Path):
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    pkg = list(rel.parts[:-1]) if rel.name != "__init__" else list(rel.parts[:-1])
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            names = [target] if node.module else [f"{target}.{a.name}" for a in node.names]
            for name in names:
                if name.startswith("ptam."):
                    yield node.lineno, name
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("ptam."):
                    yield node.lineno, a.name


def test_imports_run_one_way():
    upward = []
    for path in _modules():
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        me = _part(".".join(rel.parts))
        if me == "__init__":
            continue
        assert me in LAYERS, f"{path}: add its part to LAYERS"
        for line, target in _imports(path):
            other = _part(target)
            if other in (me, "__init__"):
                continue
            assert other in LAYERS, f"{path}:{line}: unknown part {other}"
            if LAYERS[other] >= LAYERS[me]:
                upward.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {target}")
    assert not upward, "imports that run upward or sideways:\n" + "\n".join(upward)


def test_the_import_check_sees_an_upward_import(tmp_path):
    bad = tmp_path / "ptam" / "tracking" / "x.py"
    bad.parent.mkdir(parents=True)
    bad.write_text("from ..system import System\nfrom ..mapping import bundle\n")
    found = [t for _, t in _imports_of(bad, tmp_path / "ptam")]
    assert found == ["ptam.system", "ptam.mapping"]


def _imports_of(path: Path, package: Path):
    global PACKAGE
    saved, PACKAGE = PACKAGE, package
    try:
        return list(_imports(path))
    finally:
        PACKAGE = saved


def test_module_names_are_unique():
    names: dict[str, Path] = {}
    twins = []
    for path in _modules():
        if path.name == "__init__.py":
            continue
        if path.name in names:
            twins.append(f"{names[path.name]} and {path}")
        names[path.name] = path
    assert not twins


def test_modules_and_functions_are_small():
    long_modules = [f"{p}: {n}" for p in _modules() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES]
    long_functions = []
    for path in _modules():
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            if any("njit" in ast.unparse(d) for d in node.decorator_list):
                continue  # numba kernels are one loop nest by design
            n = node.end_lineno - node.lineno + 1
            if n > MAX_FUNCTION_LINES:
                long_functions.append(f"{path}:{node.lineno} {node.name}: {n}")
    assert not long_modules and not long_functions, (long_modules, long_functions)


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_numpy_reference_or_default_config_in_the_package(path):
    tree = ast.parse(path.read_text())
    refs = [n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name.endswith("_ref")]
    assert not refs, "numpy references belong in tests/reference"
    if path.parent.name != "config":
        calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and ast.unparse(n.func) == "default_config"]
        assert not calls, "library code takes its configuration from the caller"
