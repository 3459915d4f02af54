# SPDX-License-Identifier: BSD-2-Clause
"""A tiny FMI 2.0 Co-Simulation FMU written in C and compiled in the test (``cc``), for tests that
need many cheap steps or an Integer parameter: ``Ramp`` has an Integer parameter ``n`` (start 1)
and an output ``x`` with x(t) = n * t (Euler: x += n h each step, exact for a constant rate);
``n = -13`` (``CRASH``) kills its host with SIGSEGV in the first step, as a broken FMU does. The
headers are fmpy's copy of the FMI 2.0 standard headers."""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy

from orchestrator.ssp import (
    Component,
    Connector,
    Experiment,
    ParameterSet,
    SystemStructure,
    pack_ssp,
    write_ssd,
)

HEADERS = Path(fmpy.__file__).parent / "c-code"
CRASH = -13  # the value of n that crashes the host (SOURCE)

SOURCE = r"""
#include <signal.h>
#include <stdlib.h>
#include "fmi2Functions.h"

#define CRASH -13  /* n = CRASH: the host process dies of SIGSEGV in the first fmi2DoStep */

typedef struct { double x; int n; } Ramp;

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) {
    return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions* cb, fmi2Boolean visible, fmi2Boolean logging) {
    Ramp* r = calloc(1, sizeof(Ramp)); if (r) r->n = 1; return r; }
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tol, fmi2Real t, fmi2Real t0, fmi2Boolean st,
                               fmi2Real t1) { return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { Ramp* r = c; r->x = 0; r->n = 1; return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Ramp* r = c; for (size_t i = 0; i < n; i++) { if (vr[i] != 0) return fmi2Error; v[i] = r->x; }
    return fmi2OK; }
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    Ramp* r = c; for (size_t i = 0; i < n; i++) { if (vr[i] != 1) return fmi2Error; v[i] = r->n; }
    return fmi2OK; }
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Ramp* r = c; for (size_t i = 0; i < n; i++) { if (vr[i] != 0) return fmi2Error; r->x = v[i]; }
    return fmi2OK; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) {
    Ramp* r = c; for (size_t i = 0; i < n; i++) { if (vr[i] != 1) return fmi2Error; r->n = v[i]; }
    return fmi2OK; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean np) {
    Ramp* r = c; if (r->n == CRASH) raise(SIGSEGV); r->x += r->n * h; return fmi2OK; }
#define NO(f, ...) fmi2Status f(__VA_ARGS__) { return fmi2Error; }
NO(fmi2GetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
NO(fmi2GetString, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
NO(fmi2SetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
NO(fmi2SetString, fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
NO(fmi2GetFMUstate, fmi2Component c, fmi2FMUstate* s)
NO(fmi2SetFMUstate, fmi2Component c, fmi2FMUstate s)
NO(fmi2FreeFMUstate, fmi2Component c, fmi2FMUstate* s)
NO(fmi2SerializedFMUstateSize, fmi2Component c, fmi2FMUstate s, size_t* n)
NO(fmi2SerializeFMUstate, fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
NO(fmi2DeSerializeFMUstate, fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate* s)
NO(fmi2GetDirectionalDerivative, fmi2Component c, const fmi2ValueReference u[], size_t nu,
   const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
NO(fmi2SetRealInputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n,
   const fmi2Integer o[], const fmi2Real v[])
NO(fmi2GetRealOutputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n,
   const fmi2Integer o[], fmi2Real v[])
NO(fmi2CancelStep, fmi2Component c)
NO(fmi2GetStatus, fmi2Component c, const fmi2StatusKind k, fmi2Status* v)
NO(fmi2GetRealStatus, fmi2Component c, const fmi2StatusKind k, fmi2Real* v)
NO(fmi2GetIntegerStatus, fmi2Component c, const fmi2StatusKind k, fmi2Integer* v)
NO(fmi2GetBooleanStatus, fmi2Component c, const fmi2StatusKind k, fmi2Boolean* v)
NO(fmi2GetStringStatus, fmi2Component c, const fmi2StatusKind k, fmi2String* v)
"""

MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Ramp" guid="{8c4e810f-3df3-4a00-8276-176fa3c9f000}"
  variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="Ramp" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="0" causality="output" variability="continuous"
      initial="exact"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="1" causality="parameter" variability="fixed"
      initial="exact"><Integer start="1"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="1" dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>
"""


def compiler() -> str | None:
    """The C compiler the tests use (None: none installed)."""
    return shutil.which("cc")


def build_ramp(dest: Path) -> Path:
    """Compile and pack ``dest/Ramp.fmu`` (linux64 binary)."""
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "Ramp.c").write_text(SOURCE)
    library = dest / "Ramp.so"
    subprocess.run([compiler() or "cc", "-shared", "-fPIC", "-O2", f"-I{HEADERS}", "-o", str(library),
                    str(dest / "Ramp.c")], check=True, capture_output=True)
    fmu = dest / "Ramp.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("modelDescription.xml", MODEL_DESCRIPTION)
        zf.write(library, "binaries/linux64/Ramp.so")
    return fmu


def ramp_scenario(folder: Path, fmu: Path, stop: float = 1.0, step: float = 1e-3,
                  n: int | None = None) -> Path:
    """``folder.ssp``: one Ramp component ``ramp`` (output x), no connection; ``n`` bound from an
    SSV file when given."""
    sets = (ParameterSet.of("ramp.ssv", {"n": n}),) if n is not None else ()
    ramp = Component("ramp", Path("resources/Ramp.fmu"), (Connector("x", "output", "Real"),), sets)
    write_ssd(folder, SystemStructure("ramp", (ramp,), (), Experiment(0.0, stop, step)))
    return pack_ssp(folder, {"Ramp.fmu": fmu}, folder.parent / f"{folder.name}.ssp")
