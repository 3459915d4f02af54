# SPDX-License-Identifier: BSD-2-Clause
"""The allowed import graph of the project's packages (developers' guide, issue 14).

Lower layers never import higher ones: ``controller`` (the law) imports nothing of ours,
``fmu_src`` (the FMU scripts and the paper's models: what runs inside an FMU) only ``controller``,
``fmu_src.toolchain`` (build, runtime, shim, container: nothing of it runs inside an FMU) the
models it packages, the SSP engine (the modules directly
in ``orchestrator/``) none of its applications, and each application (a subpackage of
``orchestrator``) the engine and the layers below. Imports are read with ``ast``, so an import
inside a function counts too.
"""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ENGINE = "orchestrator"
# layer -> layers it may import (besides itself)
ALLOWED = {
    "controller": set(),
    "fmu_src": {"controller"},  # the FMU scripts and models: what runs inside an FMU
    "fmu_src.toolchain": {"fmu_src", "controller"},  # the build, runtime, shim, container
    ENGINE: set(),
    "orchestrator.crosscheck": {ENGINE, "orchestrator.export"},
    "orchestrator.campaign": {ENGINE},
    "orchestrator.export": {ENGINE, "fmu_src", "fmu_src.toolchain"},
    "orchestrator.regress": {ENGINE},
    "orchestrator.experiments": {ENGINE, "orchestrator.crosscheck", "orchestrator.campaign", "controller",
                                 "fmu_src", "fmu_src.toolchain"},
}


def layer(module: str) -> str | None:
    """The layer a dotted module name belongs to (None: not ours)."""
    parts = module.split(".")
    if len(parts) > 1 and f"{parts[0]}.{parts[1]}" in ALLOWED:
        return f"{parts[0]}.{parts[1]}"
    return parts[0] if parts[0] in ALLOWED else None


def module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(name: str, is_package: bool, text: str) -> list[tuple[int, str]]:
    """(line, absolute module) of every import in module ``name``'s source, relative ones resolved."""
    package = name.split(".") if is_package else name.split(".")[:-1]
    found = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if not node.level:
                found.append((node.lineno, node.module))
                continue
            base = ".".join(package[: len(package) - node.level + 1])
            if node.module:
                found.append((node.lineno, f"{base}.{node.module}"))
            else:
                found += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
    return found


def violations(name: str, is_package: bool, text: str) -> list[str]:
    """Imports of module ``name`` that climb to a layer it may not use."""
    own = layer(name)
    assert own is not None, f"{name}: not in a known layer; add it to ALLOWED"
    return [f"line {line}: {name} imports {target} (layer {layer(target)})"
            for line, target in imports(name, is_package, text)
            if layer(target) not in (None, own) and layer(target) not in ALLOWED[own]]


SOURCES = sorted(p for top in ("controller", "fmu_src", "orchestrator") for p in (REPO / top).rglob("*.py"))


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(REPO)))
def test_imports_follow_the_layers(path: Path) -> None:
    wrong = violations(module_name(path), path.name == "__init__.py", path.read_text(encoding="utf-8"))
    assert not wrong, f"{path}:\n" + "\n".join(wrong)


def test_the_checker_catches_climbing_imports() -> None:
    """The checker itself, on made-up sources: relative, absolute and function-level imports."""
    assert violations("orchestrator.master", False, "from .experiments import metrics\n") == [
        "line 1: orchestrator.master imports orchestrator.experiments (layer orchestrator.experiments)"]
    assert violations("orchestrator", True, "from . import experiments\n") == [
        "line 1: orchestrator imports orchestrator.experiments (layer orchestrator.experiments)"]
    assert len(violations("controller.law", False, "def f():\n    import fmu_src.models\n")) == 1
    assert violations("fmu_src.models.examples", False, "from controller.params import Mode\n") == []
    assert len(violations("fmu_src.plant_core", False, "from .toolchain.build import BuildError\n")) == 1
    assert violations("orchestrator.experiments.cli", False, "from ..cli import add_command\n") == []


def import_graph() -> dict[str, set[str]]:
    """Module -> the modules of ours it imports (an import of a name inside a module is an import of
    that module; of a package, its ``__init__``), function-level imports included."""
    modules = {module_name(p): p for p in SOURCES}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets = set()
        for _, target in imports(name, path.name == "__init__.py", path.read_text(encoding="utf-8")):
            while target and target not in modules:  # 'from pkg.mod import function' -> pkg.mod
                target = target.rpartition(".")[0]
            if target and target != name:
                targets.add(target)
        graph[name] = targets
    return graph


def test_no_module_imports_itself_round_a_circle() -> None:
    """Issue 47: fmu_src/toolchain/build.py imported fmi3.py (its command line), which builds on
    build.py. Oracle: the standard library's topological sorter, which names a circle it meets."""
    try:
        tuple(graphlib.TopologicalSorter(import_graph()).static_order())
    except graphlib.CycleError as error:
        pytest.fail(f"import circle: {' -> '.join(error.args[1])}")
    with pytest.raises(graphlib.CycleError):  # the check sees a circle where there is one
        tuple(graphlib.TopologicalSorter({"a": {"b"}, "b": {"a"}}).static_order())
