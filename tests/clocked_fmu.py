# SPDX-License-Identifier: BSD-2-Clause
"""A clocked FMI 3.0 Co-Simulation FMU written in C to the standard's example of a sampled partition
(FMI 3.0, 5.2.2 "Co-Simulation with Clocks"), compiled in the test (``cc``, the official headers the
engine and the shim share in ``fmu_src/cbase/fmi``).

``Sampler`` has ``hasEventMode="true"``, an input clock ``tick`` of constant interval ``T``
(``intervalDecimal``), a continuous input ``u`` and three outputs:

* ``y`` (clocked by ``tick``): ``u`` sampled at each tick, held in between — what a clocked
  controller does; the host must activate the clock in event mode at each tick;
* ``ticks`` (clocked): the number of ticks so far;
* ``y_grid`` (unclocked): ``u`` sampled at the first communication point at or after each ``k T``,
  as an FMI 2.0 FMU with a ``sample_time`` does: right only when the host's step divides ``T``.

The Modelica Reference FMUs' ``Clocks`` model is Scheduled Execution only (its modelDescription
offers no Co-Simulation), hence this one. fmusim (the Reference FMUs' importer) runs it too: with
``--event-mode-used`` it activates the clock from a CSV input column at the rows where it is 1.
"""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import orchestrator
from fmu_src.cbase import FMI_HEADERS
from orchestrator.ssp import SSD_NAME

HEADERS = FMI_HEADERS
# /work/shared beside a checkout of /work/main, or seen from a worktree below /work/wt
SHARED = next((p for p in (Path(__file__).resolve().parents[2] / "shared", Path("/work/shared"))
               if p.is_dir()), Path("/work/shared"))
FEEDTHROUGH = SHARED / "tools" / "reference-fmus" / "3.0" / "Feedthrough.fmu"
INTERVAL = 0.1  # s, the clock's interval in the model description

SOURCE = r"""
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

enum { VR_TIME = 0, VR_TICK = 1, VR_U = 2, VR_Y = 3, VR_Y_GRID = 4, VR_TICKS = 5 };
enum { INIT, STEP, EVENT };
#define T_CLOCK INTERVAL_VALUE
#ifndef FAULT
#define FAULT 0 /* from the 4th tick on: 1 asks for another update forever, 2 asks to terminate */
#endif

typedef struct { double t, u, y, y_grid, ticks, next_grid; int mode, active, event_mode_used; } Sampler;

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
        fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean eventModeUsed, fmi3Boolean early,
        const fmi3ValueReference req[], size_t nreq, fmi3InstanceEnvironment env,
        fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback update) {
    Sampler* s = calloc(1, sizeof(Sampler));
    if (s) s->event_mode_used = eventModeUsed;
    return s; }
void fmi3FreeInstance(fmi3Instance c) { free(c); }
fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cat[]) {
    return fmi3OK; }
fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol, fmi3Float64 tolerance,
        fmi3Float64 start, fmi3Boolean stopDefined, fmi3Float64 stop) {
    Sampler* s = c; s->t = start; s->next_grid = start; s->mode = INIT; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Sampler* s = c; s->mode = s->event_mode_used ? EVENT : STEP; return fmi3OK; }
fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    Sampler* s = c; if (s->mode != STEP) return fmi3Error; s->mode = EVENT; return fmi3OK; }
fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    Sampler* s = c; if (s->mode != EVENT) return fmi3Error; s->mode = STEP; s->active = 0; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance c) { return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance c) {
    Sampler* s = c; int e = s->event_mode_used; memset(s, 0, sizeof(*s)); s->event_mode_used = e;
    return fmi3OK; }
fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[],
        size_t nv) {
    Sampler* s = c;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
            case VR_TIME: v[i] = s->t; break;
            case VR_U: v[i] = s->u; break;
            case VR_Y: v[i] = s->y; break;
            case VR_Y_GRID: v[i] = s->y_grid; break;
            case VR_TICKS: v[i] = s->ticks; break;
            default: return fmi3Error;
        } }
    return fmi3OK; }
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[],
        size_t nv) {
    Sampler* s = c;
    for (size_t i = 0; i < n; i++) { if (vr[i] != VR_U) return fmi3Error; s->u = v[i]; }
    return fmi3OK; }
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Clock v[]) {
    Sampler* s = c;
    if (s->mode != EVENT) return fmi3Error;  /* clocks are activated in event mode only */
    for (size_t i = 0; i < n; i++) { if (vr[i] != VR_TICK) return fmi3Error; if (v[i]) s->active = 1; }
    return fmi3OK; }
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Clock v[]) {
    Sampler* s = c;
    for (size_t i = 0; i < n; i++) { if (vr[i] != VR_TICK) return fmi3Error; v[i] = s->active; }
    return fmi3OK; }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        fmi3Float64 intervals[], fmi3IntervalQualifier q[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] != VR_TICK) return fmi3Error; intervals[i] = T_CLOCK; q[i] = fmi3IntervalUnchanged; }
    return fmi3OK; }
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        fmi3Float64 shifts[]) {
    (void)c;
    for (size_t i = 0; i < n; i++) { if (vr[i] != VR_TICK) return fmi3Error; shifts[i] = 0.0; }
    return fmi3OK; }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean* again, fmi3Boolean* terminate,
        fmi3Boolean* nominals, fmi3Boolean* values, fmi3Boolean* nextDefined, fmi3Float64* next) {
    Sampler* s = c;
    if (s->mode != EVENT) return fmi3Error;
    if (s->active) { s->y = s->u; s->ticks += 1; s->active = 0; }  /* the clocked partition */
    *again = FAULT == 1 && s->ticks > 3; *terminate = FAULT == 2 && s->ticks > 3;
    *nominals = fmi3False; *values = fmi3False;
    *nextDefined = fmi3False; *next = 0;
    return fmi3OK; }
fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSet,
        fmi3Boolean* event, fmi3Boolean* terminate, fmi3Boolean* early, fmi3Float64* last) {
    Sampler* s = c;
    if (s->mode != STEP) return fmi3Error;
    /* the unclocked sampler: at the first communication point at or after each k T */
    while (t >= s->next_grid - 1e-9 * T_CLOCK) { s->y_grid = s->u; s->next_grid += T_CLOCK; }
    s->t = t + h;
    *event = fmi3False; *terminate = fmi3False; *early = fmi3False; *last = s->t;
    return fmi3OK; }
"""

# The rest of the FMI 3.0 API, which Sampler does not offer: each returns fmi3Error (3). Compiled
# apart from the header, whose prototypes they need not match (nothing calls them).
UNUSED = ("InstantiateModelExchange InstantiateScheduledExecution GetFloat32 GetInt8 GetUInt8 GetInt16 "
          "GetUInt16 GetInt32 GetUInt32 GetInt64 GetUInt64 GetBoolean GetString GetBinary SetFloat32 SetInt8 "
          "SetUInt8 SetInt16 SetUInt16 SetInt32 SetUInt32 SetInt64 SetUInt64 SetBoolean SetString SetBinary "
          "GetNumberOfVariableDependencies GetVariableDependencies GetFMUState SetFMUState FreeFMUState "
          "SerializedFMUStateSize SerializeFMUState DeserializeFMUState GetDirectionalDerivative "
          "GetAdjointDerivative EnterConfigurationMode ExitConfigurationMode GetIntervalFraction "
          "GetShiftFraction SetIntervalDecimal SetIntervalFraction SetShiftDecimal "
          "SetShiftFraction EvaluateDiscreteStates EnterContinuousTimeMode CompletedIntegratorStep SetTime "
          "SetContinuousStates GetContinuousStateDerivatives GetEventIndicators GetContinuousStates "
          "GetNominalsOfContinuousStates GetNumberOfEventIndicators GetNumberOfContinuousStates "
          "GetOutputDerivatives ActivateModelPartition").split()
STUBS = "".join(f"int fmi3{name}(void) {{ return 3; }}\n" for name in UNUSED) + (
    'const char* fmi3GetVersion(void) { return "3.0"; }\n')

TOKEN = "{5a3c2f1e-9b7d-4e21-8c6a-0d1f2e3b4c5d}"
MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Sampler" instantiationToken="{token}">
  <CoSimulation modelIdentifier="Sampler" canHandleVariableCommunicationStepSize="true"{event_mode}/>
  <DefaultExperiment startTime="0" stopTime="1"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>{clock}
    <Float64 name="u" valueReference="2" causality="input" variability="continuous" start="0"/>
    <Float64 name="y_grid" valueReference="4" causality="output" variability="discrete"/>{clocked}
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="4" dependencies=""/>{clocked_outputs}
    <InitialUnknown valueReference="4"/>
  </ModelStructure>
</fmiModelDescription>
"""


MD_CLOCK = """
    <Clock name="tick" valueReference="1" causality="input" intervalVariability="{variability}"{decimal}/>"""
MD_CLOCKED = """
    <Float64 name="y" valueReference="3" causality="output" variability="discrete" clocks="1"/>
    <Float64 name="ticks" valueReference="5" causality="output" variability="discrete" clocks="1"/>"""
CLOCKED_OUTPUTS = """
    <Output valueReference="3" dependencies="2"/>
    <Output valueReference="5" dependencies=""/>"""


SAMPLER = """
      <ssd:Component name="s" source="resources/Sampler.fmu">
        <ssd:Connectors>{clock}
          <ssd:Connector name="u" kind="input"><ssc:Float64/></ssd:Connector>
          <ssd:Connector name="y_grid" kind="output"><ssc:Float64/></ssd:Connector>{clocked}
        </ssd:Connectors>
      </ssd:Component>"""
SSD_CLOCK = """
          <ssd:Connector name="tick" kind="input">
            <ssc:Clock intervalVariability="constant"/></ssd:Connector>"""
SSD_CLOCKED = """
          <ssd:Connector name="y" kind="output"><ssc:Float64/><ssd:Clock name="tick"/></ssd:Connector>
          <ssd:Connector name="ticks" kind="output"><ssc:Float64/><ssd:Clock name="tick"/></ssd:Connector>"""
FEED = """
      <ssd:Component name="f" source="resources/Feedthrough.fmu">
        <ssd:Connectors>
          <ssd:Connector name="Float64_continuous_input" kind="input"><ssc:Float64/></ssd:Connector>
          <ssd:Connector name="Float64_continuous_output" kind="output"><ssc:Float64/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>"""
SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="2.0" name="sampled"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">
  <ssd:System name="sampled">
    <ssd:Elements>{elements}
    </ssd:Elements>{connections}
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="{stop}"/>
</ssd:SystemStructureDescription>
"""
CONNECTION = """
    <ssd:Connections>
      <ssd:Connection startElement="s" startConnector="y" endElement="f"
          endConnector="Float64_continuous_input"/>
    </ssd:Connections>"""


FED = """
    <ssd:Connections>
      <ssd:Connection startElement="f" startConnector="Float64_continuous_output" endElement="s"
          endConnector="u"/>
    </ssd:Connections>"""


def build_sampler(dest: Path, interval: float = INTERVAL, clocked: bool = True, fixed: bool = False,
                  fault: int = 0) -> Path:
    """Compile and pack ``dest/Sampler.fmu`` (x86_64-linux binary) with the clock interval given;
    ``clocked`` False: the same code declaring no clock, no event mode and ``y_grid`` alone (the
    unclocked sampler with a sample time, as an FMU without clocks is written). ``fixed``: the
    clock is ``fixed`` without ``intervalDecimal``, its interval given by fmi3GetIntervalDecimal
    only (as for an interval that depends on a parameter). ``fault`` 1: from the 4th tick on its
    fmi3UpdateDiscreteStates asks for another update forever; 2: it asks to terminate."""
    dest.mkdir(parents=True, exist_ok=True)
    (dest / "sampler.c").write_text(SOURCE.replace("INTERVAL_VALUE", repr(interval)))
    (dest / "stubs.c").write_text(STUBS)
    library = dest / "Sampler.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", f"-DFAULT={fault}", f"-I{HEADERS}", "-o", str(library),
                    str(dest / "sampler.c"), str(dest / "stubs.c")], check=True, capture_output=True)
    fmu = dest / "Sampler.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zf:
        parts = {"event_mode": ' hasEventMode="true"', "clock": MD_CLOCK.format(
                     variability="fixed" if fixed else "constant",
                     decimal="" if fixed else f'\n      intervalDecimal="{interval!r}"'),
                 "clocked": MD_CLOCKED, "clocked_outputs": CLOCKED_OUTPUTS} if clocked else dict.fromkeys(
                     ("event_mode", "clock", "clocked", "clocked_outputs"), "")
        zf.writestr("modelDescription.xml", MODEL_DESCRIPTION.format(token=TOKEN, **parts))
        zf.write(library, "binaries/x86_64-linux/Sampler.so")
    return fmu


def scenario(folder: Path, fmu: Path, clocked: bool = True, feed: bool = False,
             stop: float = 0.99, fed: bool = False) -> tuple[Path, Path]:
    """The SSD folder running ``fmu`` as component ``s`` (and a Feedthrough ``f`` fed by ``s.y``;
    ``fed``: feeding ``s.u`` instead), and the input file u(t) = t (of ``f``'s input when ``fed``)."""
    (folder / "resources").mkdir(parents=True)
    shutil.copy(fmu, folder / "resources" / "Sampler.fmu")
    if feed or fed:
        shutil.copy(FEEDTHROUGH, folder / "resources")
    sampler = SAMPLER.format(clock=SSD_CLOCK if clocked else "", clocked=SSD_CLOCKED if clocked else "")
    (folder / SSD_NAME).write_text(SSD.format(elements=sampler + (FEED if feed or fed else ""), stop=stop,
                                              connections=FED if fed else CONNECTION if feed else ""))
    ramp = folder.parent / f"{folder.name}-ramp.csv"
    ramp.write_text(f"time,{'f.Float64_continuous_input' if fed else 's.u'}\n0,0\n10,10\n")
    return folder, ramp


def figure(dest: Path, step: float = 0.03) -> Path:
    """The issue's case as a figure at ``dest`` (PNG): u(t) = t sampled every T = 0.1 s by the clocked
    Sampler and by its unclocked twin, both run by ``orchestrate`` (gauss-seidel) on a grid of
    ``step`` that does not divide T, with the true sampling instants k T marked."""
    import tempfile

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        runs = {}
        for clocked in (True, False):
            fmu = build_sampler(folder / f"fmu-{clocked}", clocked=clocked)
            ssd, ramp = scenario(folder / f"s-{clocked}", fmu, clocked=clocked)
            runs[clocked] = orchestrator.run(ssd, orchestrator.RunOptions(step=step, input_file=ramp)).rows
    fig, ax = plt.subplots(figsize=(8, 4.2))
    t = runs[True]["time"]
    ax.plot(t, t, color="0.7", label="u(t) = t")
    cases = ((runs[True], "s.y", "-", "clocked FMU, ticked in event mode"),
             (runs[False], "s.y_grid", "--", f"unclocked FMU, master's step {step} s"))
    for rows, column, style, label in cases:
        line, = ax.step(t, rows[column], where="post", linestyle=style, marker=".", markersize=4,
                        label=f"{label}: rows")
        held = sorted(set(rows[column]) - {0.0})  # u = t: a held value is the instant it was sampled at
        ax.plot(held, held, "o" if style == "-" else "s", color=line.get_color(), fillstyle="none",
                label=f"{label}: sampled at t = " + ", ".join(f"{x:g}" for x in held[:4]) + " ...")
    for k in range(1, int(t[-1] / INTERVAL) + 1):
        ax.axvline(k * INTERVAL, color="0.85", linewidth=0.8, zorder=0)
    ax.set_xlabel("time [s]  (grey lines: the ticks k T, T = 0.1 s)")
    ax.set_ylabel("held sample of u")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(dest, dpi=110)
    return dest


if __name__ == "__main__":
    import sys

    print(figure(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("clock-sampling.png")))
