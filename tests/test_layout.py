# SPDX-License-Identifier: BSD-2-Clause
"""The allowed import graph of the project's packages (developers' guide, issue 14).

Lower layers never import higher ones: ``controller`` (the law) imports nothing of ours,
``fmu_src`` (the FMU scripts and the paper's models: what runs inside an FMU) only ``controller``,
``fmu_src.toolchain`` (build, runtime, shim, container: nothing of it runs inside an FMU) the
models it packages, ``fmu_src.cbase`` (the lower C layer: the FMI headers, platform.c, the C
compilers) nothing of ours, so that both the toolchain and the engine stand on it, the SSP engine
(the modules directly in ``orchestrator/``) none of its applications but the lower C layer, and
each application (a subpackage of ``orchestrator``) the engine and the layers below. Imports are
read with ``ast``, so an import inside a function counts too. C files follow the same layers
through their ``#include`` lines (below).
"""

from __future__ import annotations

import ast
import graphlib
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ENGINE = "orchestrator"
# layer -> layers it may import (besides itself)
CBASE = "fmu_src.cbase"  # the lower C layer (FMI headers, platform.c, the compilers), below both sides
ALLOWED = {
    "controller": set(),
    CBASE: set(),
    "fmu_src": {"controller"},  # the FMU scripts and models: what runs inside an FMU
    "fmu_src.toolchain": {"fmu_src", "controller", CBASE},  # the build, runtime, shim, container
    ENGINE: {CBASE},
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


# ---- C: each file includes only its own folder, the lower C layer, the folders of the layers its
# Python layer may import, and system headers (<...>) ------------------------------------------

C_SOURCES = sorted(p for top in ("controller", "fmu_src", "orchestrator") for ext in ("*.c", "*.h")
                   for p in (REPO / top).rglob(ext))
LOWER_C = (REPO / "fmu_src" / "cbase", REPO / "fmu_src" / "cbase" / "fmi")
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.MULTILINE)


def c_layer(folder: Path) -> str | None:
    """The layer a folder of C files belongs to (its Python package's)."""
    return layer(".".join(folder.relative_to(REPO).parts))


def c_violations(path: Path, text: str) -> list[str]:
    """Quoted includes of C file ``path`` that reach a folder it may not use: not its own, not the
    lower C layer's, not one of a layer its own layer may import; or that name no file."""
    own = c_layer(path.parent)
    wrong = []
    for match in INCLUDE.finditer(text):
        name, line = match.group(1), text.count("\n", 0, match.start()) + 1
        found = [d for d in (path.parent, *LOWER_C, *C_FOLDERS) if (d / name).is_file()]
        allowed = [d for d in found if d == path.parent or d in LOWER_C
                   or (own is not None and c_layer(d) in ALLOWED.get(own, set()))]
        if not allowed:
            where = ", ".join(str(d.relative_to(REPO)) for d in found) or "no folder of the project"
            wrong.append(f"line {line}: {path.relative_to(REPO)} includes \"{name}\" from {where}")
    return wrong


C_FOLDERS = sorted({p.parent for p in C_SOURCES})


@pytest.mark.parametrize("path", C_SOURCES, ids=lambda p: str(p.relative_to(REPO)))
def test_c_includes_follow_the_layers(path: Path) -> None:
    """Issue 47: one lower C layer (fmu_src/cbase) below the shim and the engine; the shim does not
    reach into the engine's folder, nor the engine into the shim's."""
    wrong = c_violations(path, path.read_text(encoding="utf-8", errors="replace"))
    assert not wrong, "\n".join(wrong)


def test_the_c_checker_catches_an_include_across() -> None:
    """The checker itself: the shim including the engine's core.h, the engine the shim's guard
    header, are caught; the lower layer, its own folder and controller/fmath.h from the models
    are not."""
    shim = REPO / "fmu_src" / "toolchain" / "shim" / "loader.c"
    engine = REPO / "orchestrator" / "native" / "core.c"
    assert len(c_violations(shim, '#include "core.h"\n')) == 1
    assert len(c_violations(engine, '#include "description.h"\n')) == 1
    assert len(c_violations(engine, '#include "nowhere.h"\n')) == 1
    assert c_violations(shim, '#include "shim.h"\n#include "platform.h"\n') == []
    assert c_violations(shim, '#include "fmi2FunctionTypes.h"\n') == []
    assert c_violations(REPO / "fmu_src" / "models" / "_dopri.c", '#include "fmath.h"\n') == []
    assert c_violations(REPO / "fmu_src" / "cbase" / "platform.c", '#include "shim.h"\n') != []
