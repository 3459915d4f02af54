# SPDX-License-Identifier: BSD-2-Clause
"""controller/fmath (Python) and controller/fmath.h (C): the same bits for every argument, and
within 1 ulp of the exact value (mpmath).

The law and the models compute exp, sin, cos and powers with these (issue 31): the C library's
last bit differs between platforms and CPUs, and the chattering laws amplify one bit to a visible
difference. tests/test_fmu_windows.py runs the same C host built for Windows under wine."""

from __future__ import annotations

import math
import random
import struct
import subprocess
import sys
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

import mpmath
import pytest
from fmu_helpers import compiled_extension

from controller import fmath
from fmu_src.toolchain.build import c_compiler

REPO = Path(__file__).resolve().parent.parent
HOST = REPO / "tests" / "fmath_host.c"
FLAGS = ("-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-ffp-contract=off")  # the extensions' arithmetic
PYTHON: dict[str, Callable[..., float]] = {"e": fmath._exp, "s": fmath._sin, "c": fmath._cos, "p": fmath._pow}
SPECIAL = (0.0, -0.0, math.inf, -math.inf, math.nan, 5e-324, -5e-324, 2.2250738585072014e-308,
           1.7976931348623157e308, -1.7976931348623157e308, 1.0, -1.0, 0.5, 2.0, math.pi, -math.pi)


def bits(x: float) -> int:
    return int(struct.unpack("<Q", struct.pack("<d", x))[0])


def from_bits(b: int) -> float:
    return float(struct.unpack("<d", struct.pack("<Q", b))[0])


def arguments(f: str, count: int, seed: int = 31) -> list[tuple[float, ...]]:
    """Arguments for ``f``: random bit patterns (every exponent), the ranges the models use, the
    borders of each algorithm's branches, and the special values."""
    rng = random.Random(seed)
    uniform, any_bits = rng.uniform, lambda: from_bits(rng.getrandbits(64))
    if f == "p":
        cases = [(any_bits(), any_bits()) for _ in range(count // 4)]
        cases += [(uniform(0.0, 2.0), uniform(0.0, 2.0)) for _ in range(count // 4)]  # |z|^(2 alpha - 1)
        cases += [(uniform(0.0, 1e3), uniform(-5.0, 5.0)) for _ in range(count // 4)]
        cases += [(from_bits(rng.getrandbits(63)), -0.2) for _ in range(count // 8)]  # the step size control
        cases += [(uniform(-10.0, 10.0), float(rng.randint(-40, 40))) for _ in range(count // 8)]
        cases += [(x, y) for x in SPECIAL for y in SPECIAL]
        return cases
    xs = [any_bits() for _ in range(count // 4)] + [uniform(-1.0, 1.0) for _ in range(count // 8)]
    if f == "e":
        xs += [uniform(-750.0, 750.0) for _ in range(count // 4)]
        ranges = ((-746.0, -700.0), (-1e-8, 1e-8), (-2.0, 2.0))  # subnormal results, tiny x, one ln 2
        xs += [uniform(lo, hi) for lo, hi in ranges for _ in range(count // 8)]
    else:
        xs += [uniform(-10.0, 10.0) for _ in range(count // 4)]
        xs += [uniform(-2e6, 2e6) for _ in range(count // 8)]
        near = [k * math.pi / 2 for k in range(-40, 41)] + [6381956970095103 * 2.0**797]  # hardest reductions
        xs += [math.nextafter(x, x + rng.choice((-1, 1)) * math.inf) if rng.random() < 0.5 else x
               for x in near for _ in range(count // (8 * len(near)) + 1)]
        xs += [math.ldexp(uniform(0.5, 1.0), rng.randint(20, 1023)) for _ in range(count // 8)]
    return [(x,) for x in [*xs, *SPECIAL]]


@pytest.fixture(scope="module")
def host(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/fmath_host.c built for this machine with the FMU build's compiler and arithmetic flags."""
    out = tmp_path_factory.mktemp("fmath") / "fmath_host"
    subprocess.run([c_compiler()[0], *FLAGS, f"-I{REPO / 'controller'}", "-o", str(out), str(HOST), "-lm"],
                   check=True)
    return out


def host_input(f: str, cases: list[tuple[float, ...]]) -> str:
    """The host's input lines for ``f`` over ``cases``."""
    return "".join(f"{f} " + " ".join(f"{bits(v):016x}" for v in case) + "\n" for case in cases)


def host_results(output: str) -> list[int]:
    return [int(line, 16) for line in output.split()]


def python_results(f: str, cases: list[tuple[float, ...]]) -> Iterator[int]:
    function = PYTHON[f]
    return (bits(function(*case)) for case in cases)


@pytest.mark.parametrize("f", PYTHON)
def test_python_and_c_give_the_same_bits(host: Path, f: str) -> None:
    cases = arguments(f, 200_000)
    c = host_results(subprocess.run([str(host)], input=host_input(f, cases), capture_output=True, text=True,
                                    check=True).stdout)
    assert len(c) == len(cases)
    differing = [(case, hex(a), hex(b)) for case, a, b in zip(cases, c, python_results(f, cases), strict=True)
                 if a != b]
    assert not differing, f"{len(differing)} of {len(cases)} differ, e.g. {differing[:3]}"


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    """controller/_fmath.c compiled as the FMU build compiles it (what fmath.py calls in an FMU)."""
    return compiled_extension("controller._fmath", tmp_path_factory.mktemp("fmath_module"))


@pytest.mark.parametrize("f", PYTHON)
def test_the_compiled_module_gives_the_same_bits(compiled: ModuleType, f: str) -> None:
    function = getattr(compiled, {"e": "exp", "s": "sin", "c": "cos", "p": "pow"}[f])
    cases = arguments(f, 100_000, seed=5)
    differing = [case for case, b in zip(cases, python_results(f, cases), strict=True)
                 if bits(function(*case)) != b]
    assert not differing, f"{len(differing)} of {len(cases)} differ, e.g. {differing[:3]}"


def test_every_fmu_carries_the_compiled_functions(built: Path) -> None:
    """Each FMU bundles controller.fmath (its models call it) and with it _fmath for both platforms."""
    for fmu in sorted((built / "fmus").glob("*.fmu")):
        names = zipfile.ZipFile(fmu).namelist()
        for suffix in ("/controller/fmath.py", "/controller/_fmath.abi3.so", "/controller/_fmath.pyd"):
            assert any(n.endswith(suffix) for n in names), (fmu.name, suffix)


def ulps(ours: float, exact: mpmath.mpf) -> float:
    """|ours - exact| in units of the last place of the exact value rounded to a double."""
    nearest = float(exact)
    if math.isinf(nearest):
        return 0.0 if ours == nearest else math.inf
    return float(abs(mpmath.mpf(ours) - exact) / mpmath.mpf(math.ulp(nearest)))


@pytest.mark.parametrize("f", PYTHON)
def test_within_one_ulp_of_the_exact_value(f: str) -> None:
    """Against mpmath's values at 120 bits (an independent, arbitrary-precision implementation),
    wherever the result is finite and not subnormal: below 1 ulp, as musl documents. (glibc is no
    oracle here: its cos(5.319372648326541e255) is 8 ulp off, fmath's is correctly rounded.)"""
    exact_of = {"e": mpmath.exp, "s": mpmath.sin, "c": mpmath.cos, "p": mpmath.power}[f]
    worst, where = 0.0, None
    with mpmath.workprec(120):
        for case in arguments(f, 12_000, seed=7):
            ours = PYTHON[f](*case)
            # specials are compared with the Python operators below; subnormals have no relative ulp
            if not math.isfinite(ours) or not all(map(math.isfinite, case)) or abs(ours) < sys.float_info.min:
                continue
            if f == "p" and case[0] < 0.0 and case[1] != math.floor(case[1]):
                continue  # nan: a complex power
            error = ulps(ours, exact_of(*map(mpmath.mpf, case)))
            if error > worst:
                worst, where = error, case
    assert worst < 1.0, f"{worst} ulp at {where}"


def test_exact_values() -> None:
    """Values the functions must hit exactly (independent of any libm)."""
    assert fmath.exp(0.0) == 1.0 and fmath.sin(0.0) == 0.0 and fmath.cos(0.0) == 1.0
    assert math.copysign(1.0, fmath.sin(-0.0)) == -1.0
    assert fmath.power(2.0, 10.0) == 1024.0 and fmath.power(9.0, 0.5) == 3.0
    assert fmath.power(2.0, -1074.0) == 5e-324 and fmath.power(-2.0, 3.0) == -8.0
    assert fmath.power(0.25, 0.5) == 0.5 and fmath.power(10.0, 2.0) == 100.0


def test_the_wrappers_keep_the_python_contracts() -> None:
    """exp, sin, cos and power raise where math.exp, math.sin, math.cos and float ** raise, with
    their exception types, and pass nan through."""
    for wrapper, reference, arg in ((fmath.exp, math.exp, 710.0), (fmath.sin, math.sin, math.inf),
                                    (fmath.cos, math.cos, -math.inf)):
        with pytest.raises(Exception) as ours:
            wrapper(arg)
        with pytest.raises(Exception) as python:
            reference(arg)
        assert (ours.type, str(ours.value)) == (python.type, str(python.value))
        assert math.isnan(wrapper(math.nan))
    assert fmath.exp(-math.inf) == 0.0 and fmath.exp(math.inf) == math.inf and fmath.exp(-800.0) == 0.0
    odd_powers = [(-8.0, 3.0), (-8.0, -3.0), (-0.0, 3.0), (-0.0, 2.0)]
    for x, y in [(x, y) for x in SPECIAL for y in SPECIAL] + odd_powers:
        if x < 0.0 and math.isfinite(x) and math.isfinite(y) and y != math.floor(y):  # ** goes complex
            with pytest.raises(ValueError, match="fractional power"):
                fmath.power(x, y)
            continue
        try:
            expected: float | type[BaseException] = x**y
        except ZeroDivisionError:
            expected = ZeroDivisionError
        except OverflowError:
            expected = OverflowError
        if isinstance(expected, type):
            with pytest.raises(expected):
                fmath.power(x, y)
        else:
            got = fmath.power(x, y)
            same = bits(got) == bits(expected) or (math.isnan(got) and math.isnan(expected))
            assert same, (x, y, got, expected)
    with pytest.raises(OverflowError, match="math range error"):
        fmath.power(10.0, 400.0)
