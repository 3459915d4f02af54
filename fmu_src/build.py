"""Build the project's five FMUs with pythonfmu, reproducibly and safe to load side by side.

All pythonfmu FMUs in one process share one interpreter and one module cache, and each FMU's
``resources`` folder goes to ``sys.path[0]``. So two FMUs that bundle modules of the same name
see whichever was imported first. To rule that out, every FMU bundles its script as
``ftc_<model>_<hash>.py`` and the code it needs (modules of ``fmu_src`` and ``controller``) as a
package ``_ftc_<model>_<hash>``, where ``<hash>`` is a digest of every bundled byte. Only the
script's own ``from fmu_src... / from controller... import`` lines are rewritten (with ``ast``);
bundled modules must import each other relatively.

pythonfmu's linux64 binary does not link libpython, so a host without Python in its process
cannot load it. The build compiles ``fmu_src/shim/fmi2_shim.c`` with the system C compiler into
``binaries/linux64/<model>.so``, keeps pythonfmu's binary beside it as ``<model>_pythonfmu.so``
and records the building interpreter (its shared libpython, home and site-packages) in
``binaries/linux64/python_env.txt``; the shim loads that Python when the host has none (see the
shim's header). The win64 binary stays as pythonfmu made it.

The archive is normalized afterwards: GUID derived from the digest, no generation date, sorted
entries with fixed timestamps, ``resources/requirements.txt`` with the pinned run-time imports.
Rebuilding the same sources with the same compiler gives identical bytes.

Usage: ``python -m fmu_src.build DEST [--model NAME]...``
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import uuid
import zipfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

import pythonfmu
from pythonfmu import FmuBuilder

__all__ = ["FMU_SCRIPTS", "BuildError", "build_all", "build_fmu", "c_compiler", "main", "python_env_record"]

REPO_ROOT = Path(__file__).resolve().parent.parent
LOCAL_PACKAGES = ("fmu_src", "controller")
# Model name -> script in fmu_src/ (the model names are a contract with the scenarios).
FMU_SCRIPTS = {
    "Reference": "reference.py",
    "FixedTimeController": "fixed_time_controller.py",
    "Actuator": "actuator.py",
    "Example1Plant": "example1_plant.py",
    "PendulumPlant": "pendulum_plant.py",
}
BUILD_OPTIONS = {"canGetAndSetFMUstate": True}
# Bump when the staging or normalization below changes the archive layout.
BUILD_FORMAT = "2"
SHIM_SOURCE = Path("fmu_src", "shim", "fmi2_shim.c")  # relative to the source root
# No debug info, build id or symbol table, so the bytes depend only on source, compiler and flags.
SHIM_FLAGS = tuple(
    "-std=c11 -O2 -fPIC -shared -fvisibility=hidden -g0 -Wall -Wextra -Wno-format-truncation "
    "-Wl,--build-id=none -s".split()
)
SHIM_LIBS = ("-ldl", "-pthread")
PYTHON_ENV = "binaries/linux64/python_env.txt"
CLASS_LINE = re.compile(r"^class (\w+)\(\s*Fmi2Slave\s*\)\s*:", re.MULTILINE)  # pythonfmu's loader regex
ZIP_DATE = (1980, 1, 1, 0, 0, 0)
GUID_NAMESPACE = uuid.UUID("5b0f3a52-4c1e-4d59-9a4e-2f6f1c1e7a10")


class BuildError(RuntimeError):
    """An FMU cannot be built from these sources; the message names the file."""


@dataclass(frozen=True)
class Bundle:
    """What one FMU carries: its script, the local modules it needs and its run-time imports."""

    model: str
    script: Path
    modules: dict[str, Path]  # dotted name (e.g. "controller.law") -> source file
    third_party: frozenset[str]  # top-level names of non-local, non-stdlib imports

    def digest(self, native: str) -> str:
        """SHA-256 over everything that ends up in the archive (sources, pythonfmu version, format,
        and ``native``: the shim's source, compiler, flags and recorded Python)."""
        h = hashlib.sha256()
        options = repr(sorted(BUILD_OPTIONS.items()))
        for part in (BUILD_FORMAT, pythonfmu.__version__, self.model, options, native):
            h.update(part.encode() + b"\0")
        h.update(self.script.read_bytes() + b"\0")
        for name in sorted(self.modules):
            h.update(name.encode() + b"\0" + self.modules[name].read_bytes() + b"\0")
        return h.hexdigest()


def _is_local(module: str | None) -> bool:
    return module is not None and module.split(".")[0] in LOCAL_PACKAGES


def _parse(path: Path) -> ast.Module:
    try:
        return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    except (OSError, SyntaxError) as error:
        raise BuildError(f"{path}: cannot read or parse: {error}") from error


def _module_file(root: Path, name: str) -> Path:
    path = root.joinpath(*name.split(".")).with_suffix(".py")
    if not path.is_file():
        raise BuildError(f"module {name} not found at {path}")
    return path


def collect_bundle(model: str, root: Path = REPO_ROOT) -> Bundle:
    """The script of ``model`` and the closure of local modules it imports, checked with ``ast``."""
    if model not in FMU_SCRIPTS:
        raise BuildError(f"unknown FMU {model!r}; known: {', '.join(FMU_SCRIPTS)}")
    script = root / "fmu_src" / FMU_SCRIPTS[model]
    if not script.is_file():
        raise BuildError(f"FMU script for {model} not found: {script}")
    third_party: set[str] = set()
    pending: list[str] = []
    for node in ast.walk(_parse(script)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if _is_local(alias.name):
                    raise BuildError(f"{script}:{node.lineno}: use 'from {alias.name} import ...'")
                third_party.add(alias.name.split(".")[0])
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                raise BuildError(f"{script}:{node.lineno}: the FMU script must use absolute imports")
            assert node.module is not None  # an absolute "from X import" always names X
            if _is_local(node.module):
                pending.append(node.module)
            else:
                third_party.add(node.module.split(".")[0])

    modules: dict[str, Path] = {}
    while pending:
        name = pending.pop()
        if name in modules:
            continue
        path = modules[name] = _module_file(root, name)
        package = name.rpartition(".")[0]
        for node in ast.walk(_parse(path)):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    if _is_local(alias.name):
                        raise BuildError(
                            f"{path}:{node.lineno}: bundled modules must import {alias.name} relatively"
                        )
                    third_party.add(alias.name.split(".")[0])
            elif isinstance(node, ast.ImportFrom):
                if node.level == 0:
                    assert node.module is not None  # an absolute "from X import" always names X
                    if _is_local(node.module):
                        raise BuildError(
                            f"{path}:{node.lineno}: bundled modules must import {node.module} relatively"
                        )
                    third_party.add(node.module.split(".")[0])
                elif node.level == 1:
                    targets = [node.module] if node.module else [alias.name for alias in node.names]
                    pending.extend(f"{package}.{target}" for target in targets)
                else:
                    raise BuildError(
                        f"{path}:{node.lineno}: relative imports beyond the package cannot be bundled"
                    )
    ignored = set(sys.stdlib_module_names) | {"__future__", "pythonfmu"}
    return Bundle(model, script, modules, frozenset(third_party - ignored))


def c_compiler() -> tuple[str, str]:
    """The system C compiler (``$CC``, else ``cc``, else ``gcc`` from PATH) and its version line."""
    for name in (os.environ.get("CC"), "cc", "gcc"):
        path = shutil.which(name) if name else None
        if path:
            try:
                version = subprocess.run([path, "--version"], capture_output=True, text=True, check=True)
            except (OSError, subprocess.CalledProcessError) as error:
                raise BuildError(f"C compiler {path} does not run: {error}") from error
            return path, version.stdout.partition("\n")[0]
    raise BuildError(
        "no C compiler (CC, cc or gcc on PATH) to build the FMI shim binaries/linux64/<model>.so; "
        "install one, e.g. apt-get install gcc"
    )


def python_env_record() -> str:
    """``binaries/linux64/python_env.txt``: the Python the shim loads when the host has none
    (this interpreter's shared libpython, its home and its site-packages, where the packages of
    requirements.txt are installed)."""
    lines = [
        "# The Python that binaries/linux64/<model>.so (fmu_src/shim/fmi2_shim.c) loads when the",
        "# host process has none: recorded from the interpreter that built the FMU.",
        "# Overrides: FTC_PYTHON_LIBRARY (libpython), FTC_PYTHON_PATH (site dirs, ':'-separated),",
        "# PYTHONHOME.",
        f"version={sys.version_info.major}.{sys.version_info.minor}",
    ]
    libdir, soname = sysconfig.get_config_var("LIBDIR"), sysconfig.get_config_var("INSTSONAME")
    if sysconfig.get_config_var("Py_ENABLE_SHARED") and libdir and soname and Path(libdir, soname).is_file():
        lines.append(f"library={Path(libdir, soname)}")
    else:
        lines.append("# no library: the building Python has no shared libpython (not --enable-shared)")
    home = sys.base_prefix
    if sys.base_exec_prefix != sys.base_prefix:  # PYTHONHOME's prefix:exec_prefix form
        home += f":{sys.base_exec_prefix}"
    lines.append(f"home={home}")
    paths = sysconfig.get_paths()
    lines += [f"path={p}" for p in dict.fromkeys((paths["purelib"], paths["platlib"]))]
    return "\n".join(lines) + "\n"


def compile_shim(source: Path, where: Path) -> bytes:
    """Compile the FMI shim; returns the shared object's bytes (the same for the same inputs)."""
    compiler, _ = c_compiler()
    work = where / "shim"
    work.mkdir(parents=True)
    shutil.copyfile(source, work / source.name)
    command = [compiler, *SHIM_FLAGS, "-o", "shim.so", source.name, *SHIM_LIBS]
    result = subprocess.run(command, cwd=work, capture_output=True, text=True)
    if result.returncode != 0:
        raise BuildError(f"{source}: {compiler} failed:\n{result.stderr.strip()}")
    return (work / "shim.so").read_bytes()


def native_identity(root: Path = REPO_ROOT) -> str:
    """What makes the linux64 binaries and python_env.txt: shim source, compiler, flags, record."""
    source = root / SHIM_SOURCE
    if not source.is_file():
        raise BuildError(f"FMI shim source not found: {source}")
    text = hashlib.sha256(source.read_bytes()).hexdigest()
    return "\0".join((text, c_compiler()[1], repr(SHIM_FLAGS + SHIM_LIBS), python_env_record()))


def requirements(bundle: Bundle) -> str:
    """``resources/requirements.txt``: the pinned distributions the FMU imports at run time."""
    distributions = importlib.metadata.packages_distributions()
    lines = [f"# Run-time imports of {bundle.model} besides the standard library and the bundled pythonfmu."]
    for name in sorted(bundle.third_party):
        if name not in distributions:
            raise BuildError(f"{bundle.model}: imported package {name!r} is not installed")
        for dist in sorted(set(distributions[name])):
            lines.append(f"{dist}=={importlib.metadata.version(dist)}")
    return "\n".join(lines) + "\n"


def _rewrite_script(bundle: Bundle, package: str) -> str:
    """The script text with only its local ``from X import ...`` lines pointed into ``package``."""
    lines = bundle.script.read_text(encoding="utf-8").splitlines(keepends=True)
    tree = _parse(bundle.script)
    for node in sorted(tree.body, key=lambda n: n.lineno, reverse=True):
        if isinstance(node, ast.ImportFrom) and _is_local(node.module):
            new = ast.ImportFrom(module=f"{package}.{node.module}", names=node.names, level=0)
            lines[node.lineno - 1 : node.end_lineno] = [ast.unparse(new) + "\n"]
    text = "".join(lines)
    for found in ast.walk(ast.parse(text)):
        if isinstance(found, ast.ImportFrom) and _is_local(found.module):
            raise BuildError(
                f"{bundle.script}:{found.lineno}: local import of {found.module} outside module level"
            )
    classes = CLASS_LINE.findall(text)
    if classes != [bundle.model]:
        raise BuildError(
            f"{bundle.script}: expected exactly one line 'class {bundle.model}(Fmi2Slave):' "
            f"(pythonfmu's loader matches it literally), found {classes}"
        )
    return text


def _stage(bundle: Bundle, digest: str, where: Path) -> tuple[Path, Path]:
    """Write the rewritten script and the uniquely named package; return both paths."""
    package = f"_ftc_{bundle.model.lower()}_{digest[:12]}"
    package_dir = where / package
    package_dir.mkdir(parents=True)
    init = f'"""Code bundled into the {bundle.model} FMU under a name no other FMU can use."""\n'
    (package_dir / "__init__.py").write_text(init, encoding="utf-8")
    for name, source in bundle.modules.items():
        target = package_dir.joinpath(*name.split(".")).with_suffix(".py")
        for parent in reversed(target.relative_to(package_dir).parents):  # outermost first
            if parent != Path("."):
                (package_dir / parent).mkdir(exist_ok=True)
                (package_dir / parent / "__init__.py").write_text(init, encoding="utf-8")
        if target.name != "__init__.py":
            shutil.copyfile(source, target)
    script = where / f"ftc_{bundle.model.lower()}_{digest[:12]}.py"
    script.write_text(_rewrite_script(bundle, package), encoding="utf-8")
    return script, package_dir


@contextmanager
def _isolated_imports() -> Iterator[None]:
    """Undo what pythonfmu's builder does to ``sys.path`` and ``sys.modules`` (it imports the script)."""
    path, modules, bytecode = list(sys.path), set(sys.modules), sys.dont_write_bytecode
    sys.dont_write_bytecode = True
    try:
        yield
    finally:
        sys.path[:] = path
        for name in set(sys.modules) - modules:
            if name.startswith("ftc_") or name.startswith("_ftc_"):
                del sys.modules[name]
        sys.dont_write_bytecode = bytecode


def _normalized_description(xml: bytes, digest: str, model: str) -> bytes:
    root = ElementTree.fromstring(xml)
    root.set("guid", "{" + str(uuid.uuid5(GUID_NAMESPACE, f"{model}:{digest}")) + "}")
    root.attrib.pop("generationDateAndTime", None)
    ElementTree.indent(root, space="  ")
    return ElementTree.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"


def _write_normalized(raw_fmu: Path, target: Path, bundle: Bundle, digest: str, shim: bytes) -> None:
    """Copy the archive with the shim in front of pythonfmu's linux64 binary, a deterministic
    description, fixed timestamps and sorted entries."""
    with zipfile.ZipFile(raw_fmu) as archive:
        entries = {name: archive.read(name) for name in archive.namelist() if not name.endswith("/")}
    binary = f"binaries/linux64/{bundle.model}.so"
    if binary not in entries:
        raise BuildError(f"pythonfmu's archive for {bundle.model} has no {binary}")
    entries[f"binaries/linux64/{bundle.model}_pythonfmu.so"] = entries[binary]
    entries[binary] = shim
    entries[PYTHON_ENV] = python_env_record().encode()
    entries["modelDescription.xml"] = _normalized_description(
        entries["modelDescription.xml"], digest, bundle.model
    )
    entries["resources/requirements.txt"] = requirements(bundle).encode()
    with zipfile.ZipFile(target, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            archive.writestr(info, entries[name])


def build_fmu(model: str, dest: Path, root: Path = REPO_ROOT) -> Path:
    """Build one FMU into ``dest/<model>.fmu`` from the sources under ``root``."""
    bundle = collect_bundle(model, root)
    digest = bundle.digest(native_identity(root))
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"ftc_build_{model}_") as tmp:
        script, package_dir = _stage(bundle, digest, Path(tmp) / "stage")
        with _isolated_imports():
            try:
                raw = FmuBuilder.build_FMU(
                    script, dest=Path(tmp) / "raw", project_files=[package_dir], **BUILD_OPTIONS
                )
            except Exception as error:
                raise BuildError(
                    f"pythonfmu could not build {model} from {bundle.script}: {error}"
                ) from error
        shim = compile_shim(root / SHIM_SOURCE, Path(tmp))
        target = dest / f"{model}.fmu"
        _write_normalized(Path(raw), target, bundle, digest, shim)
    return target


def build_all(dest: Path, root: Path = REPO_ROOT) -> list[Path]:
    """Build every FMU of the project into ``dest``; returns the paths in FMU_SCRIPTS order."""
    return [build_fmu(model, dest, root) for model in FMU_SCRIPTS]


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: build FMUs into a folder; prints one path per line."""
    parser = argparse.ArgumentParser(prog="python -m fmu_src.build", description=__doc__.split("\n\n")[0])
    parser.add_argument("dest", type=Path, help="output folder, e.g. build/fmus")
    parser.add_argument(
        "--model", action="append", choices=list(FMU_SCRIPTS), help="build only these (repeatable)"
    )
    options = parser.parse_args(argv)
    try:
        paths = [build_fmu(model, options.dest) for model in options.model or FMU_SCRIPTS]
    except BuildError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    for path in paths:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
