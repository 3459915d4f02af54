# SPDX-License-Identifier: BSD-2-Clause
"""The controller FMUs' own documentation, ``documentation/index.html`` (the FMI 3.0 entry point; FMI
2.0's ``documentation/_main.html`` leads to it), written by the build from the FMU's model
description, so that it cannot drift from the FMU: every variable with its description, start value,
range and unit as the FMU declares them, beside what this module adds per variable (the paper's
equation, the allowed range its check enforces). A controller variable this module does not know is
a build error. Not bundled into the FMUs.

The page: the plant class assumed (the paper's system (1)), the inputs and how to feed them, the call
order per communication step, the parameters, the discretization, a wiring diagram and a worked
example around a plant that is not the paper's (its code runs as printed: ``tests/test_controller_doc.py``).
"""

from __future__ import annotations

import html
import re
from xml.etree import ElementTree

from ..controller_core import DERIVATIVES, ORDERS, controller_model

__all__ = ["WORKED_EXAMPLES", "controller_documentation", "example_code"]

INDEX = "documentation/index.html"
MAIN = "documentation/_main.html"  # FMI 2.0's entry point
PAPER = ("\"Neural network-based adaptive fixed-time control for nonlinear systems with actuator faults, "
         "unmodeled dynamics, and input dead-zone\"")

# base name (k1 -> k, eta2_0 -> eta_0, mu3 -> mu) -> (meaning, the paper's equation, allowed range)
PARAMETERS = {
    "k": ("fast (fixed-time) gain of step i: the term -k_i sig(z_i)^(2 alpha - 1)", "(37), (54), (68)",
          "> 0 (unused when mode = 1)"),
    "q": ("gain of step i's term -q_i sig(z_i)^(2 beta - 1)", "(37), (54), (68)", "> 0"),
    "a": ("NN design constant of step i: the weight 1 / (2 a_i^2) of its RBF term and adaptive law",
          "(37), (38), (54), (55), (68), (69)", "> 0"),
    "kappa": ("adaptation gain of eta_hat_i", "(38), (55), (69)", "> 0"),
    "rho": ("leakage rho_i of eta_hat_i (sigma modification)", "(38), (55), (69)", "> 0"),
    "rho_bar": ("second leakage rho_bar_i of eta_hat_i", "(38), (55), (69)", "> 0"),
    "alpha": ("exponent of the fast term sig(z)^(2 alpha - 1); the paper leaves it open", "(37), (83)",
              "> 1"),
    "beta": ("exponent of the term sig(z)^(2 beta - 1); the paper leaves it open", "(37), (83)",
             "0.5 < beta < 1 (a continuous law)"),
    "mode": ("0: the paper's fixed-time law; 1: its finite-time comparison method [36] (k_i = 0)", "(37)",
             "0 or 1"),
    "a_bar": ("decay rate of the dynamic signal r", "(18), (20)", "> 0"),
    "gamma_gain": ("gain of |x1|^gamma_power in r' (the bound of the unmodeled dynamics' input)", "(20)",
                   ">= 0"),
    "gamma_power": ("power of |x1| in r'", "(20)", ">= 0"),
    "d_r": ("constant term of r'", "(18), (20)", ">= 0"),
    "r0": ("initial value of r", "(18)", ">= 0"),
    "eta_0": ("initial value of eta_hat_i", "(38)", ">= 0"),
    "mu": ("center of RBF neuron j (the neuron is centered at mu_j times the ones vector)", "(24)",
           "finite"),
    "tau": ("width of the Gaussian RBF neurons", "(24)", "> 0"),
    "substeps": ("RK4 sub-steps per communication step for r and eta_hat (not in the paper)", "-", ">= 1"),
    "discretization": ("0: explicit (the paper's law at the sample, held); 1: semi-implicit (each step's "
                       "feedback min(phi(|z|), |z| / (b_max sample_time)): no chattering at coarse steps)",
                       "- (SPEC 10)", "0 or 1"),
    "sample_time": ("the sample time h the semi-implicit law assumes: the communication step", "-",
                    "> 0 (semi-implicit only)"),
    "b_max": ("an upper bound b_M of the plant's input gains g_i (Assumption 3), used by the semi-implicit "
              "law; a larger value is a bound too and makes its one-sample correction gentler",
              "Assumption 3",
              "> 0 (semi-implicit only)"),
    "nn_term": ("1: the NN term eta_hat_i z_i P_i^T P_i / (2 a_i^2) in every zeta_i (the paper's law); "
                "0: left out, an ablation (not in the paper; eta_hat still adapts and is an output)",
                "(37), (54), (68)",
                "0 or 1"),
}
PARAMETER_COLUMNS = ["parameter", "type", "default", "unit", "meaning", "equation", "allowed",
                     "declared range"]
OUTPUTS = {
    "v": ("the control v = zeta_n, to the actuator or the plant's input", "(68)"),
    "z": ("error z_i = x_i - zeta_(i-1) (z_1 = x1 - yd: the tracking error)", "(26)"),
    "zeta": ("virtual control of step i", "(37), (54)"),
    "eta_hat": ("adaptive estimate eta_hat_i (the NN weight norm, scaled)", "(38), (55), (69)"),
    "r": ("dynamic signal r that bounds the unmodeled dynamics", "(20)"),
}


def _base(name: str) -> str:
    """k1 -> k, eta2_0 -> eta_0, eta1_hat -> eta_hat, mu3 -> mu; r0, b_max, ... as they are."""
    if name in PARAMETERS or name in OUTPUTS:
        return name
    if re.fullmatch(r"eta\d+_0", name):
        return "eta_0"
    if re.fullmatch(r"eta\d+_hat", name):
        return "eta_hat"
    return re.sub(r"\d+$", "", name)


# One plant per order that is not the paper's: (description, right-hand side, initial state, b_max).
WORKED_EXAMPLES = {
    1: ("a first-order thermal process: C T' = -(T - T_a) / R_th + u with C = 0.5, R_th = 2, T_a = 0 "
        "(x1 = T)",
        "[(-x[0] / 2.0 + u) / 0.5]", "[0.5]", 4.0),
    2: ("a mass-spring-damper: m x'' + c x' + k x = u with m = 1, c = 0.4, k = 2 (x1 = position, "
        "x2 = velocity)",
        "[x[1], (u - 0.4 * x[1] - 2.0 * x[0]) / 1.0]", "[0.5, 0.0]", 2.0),
    3: ("the mass-spring-damper of order 2 driven through a first-order force actuator: F' = (u - F) / 0.05 "
        "(x1 = position, x2 = velocity, x3 = force)",
        "[x[1], x[2] - 0.4 * x[1] - 2.0 * x[0], (u - x[2]) / 0.05]", "[0.5, 0.0, 0.0]", 40.0),
    4: ("a flexible drive: a motor and a load of unit inertia joined by a shaft of stiffness 4, the motor "
        "torque u (x1 = load angle, x2 = load speed, x3 = shaft torque, x4 = its rate)",
        "[x[1], x[2], x[3], 4.0 * (u - 2.0 * x[2])]", "[0.5, 0.0, 0.0, 0.0]", 8.0),
}


def example_code(n: int) -> str:
    """The worked example of order n: Python with fmpy, runnable beside the FMU file."""
    description, rhs, x0, b_max = WORKED_EXAMPLES[n]
    inputs = [*(f"x{i}" for i in range(1, n + 1)), *DERIVATIVES[: n + 1]]
    return f'''# {controller_model(n)} around {description}.
import math
import shutil

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

FMU = "{controller_model(n)}.fmu"
H = 1e-3                      # the communication step, and the controller's sample_time
STOP = 5.0


def plant(x, u):              # the plant's right-hand side, states x = [x1..x{n}], input u
    return {rhs}


def reference(t):             # yd = 0.5 sin t and its derivatives up to order {n}, at the same t
    return [0.5 * math.sin(t + j * math.pi / 2) for j in range({n + 1})]


def rk4(x, u, h):             # the plant over one step with u held (zero-order hold)
    k1 = plant(x, u)
    k2 = plant([a + h / 2 * b for a, b in zip(x, k1)], u)
    k3 = plant([a + h / 2 * b for a, b in zip(x, k2)], u)
    k4 = plant([a + h * b for a, b in zip(x, k3)], u)
    return [a + h / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]


md = read_model_description(FMU)
vr = {{v.name: v.valueReference for v in md.modelVariables}}
folder = extract(FMU)                           # fmpy unpacks into TMPDIR: removed at the end
controller = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                       modelIdentifier=md.coSimulation.modelIdentifier, instanceName="controller")
controller.instantiate()
controller.setupExperiment(startTime=0.0)
controller.enterInitializationMode()
controller.setInteger([vr["discretization"]], [1])                # semi-implicit
controller.setReal([vr["sample_time"], vr["b_max"]], [H, {b_max!r}])     # b_max >= every input gain
controller.exitInitializationMode()

inputs = [vr[name] for name in {inputs!r}]
x = {x0}
for k in range(round(STOP / H)):
    t = k * H                                   # time from the step count: no drift
    controller.setReal(inputs, [*x, *reference(t)])  # 1. the inputs at t
    v = controller.getReal([vr["v"]])[0]            # 2. the control for them (direct feedthrough)
    x = rk4(x, v, H)                                # 3. the plant over [t, t + H], v held
    controller.doStep(t, H)                         # 4. the controller's states over the same step
controller.terminate()
controller.freeInstance()
shutil.rmtree(folder)
error = x[0] - reference(STOP)[0]
print(f"tracking error at t = {{STOP}} s: {{error:.2e}}")
'''


def _variables(xml: bytes) -> list[dict[str, str]]:
    root = ElementTree.fromstring(xml)
    out = []
    for v in root.iterfind("ModelVariables/ScalarVariable"):
        typed = next(iter(v))
        out.append({"name": v.get("name", ""), "causality": v.get("causality", ""),
                    "description": v.get("description", ""), "type": typed.tag,
                    "start": typed.get("start", ""),
                    "min": typed.get("min", ""), "max": typed.get("max", ""), "unit": typed.get("unit", "")})
    return out


def _table(header: list[str], rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "\n".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table>\n<tr>{head}</tr>\n{body}\n</table>"


def _wiring(n: int) -> str:
    """An SVG diagram: reference -> controller -> actuator -> plant, the states back."""
    states = ", ".join(f"x{i}" for i in range(1, n + 1))
    yds = ", ".join(DERIVATIVES[: n + 1])
    boxes = [(20, "Reference", "yd and its derivatives"), (250, controller_model(n), "this FMU"),
             (480, "Actuator", "optional: fault, dead-zone"), (710, "Plant", f"order {n}, y = x1")]
    parts = ['<svg xmlns="http://www.w3.org/2000/svg" width="900" height="230" font-family="sans-serif" '
             'font-size="12" role="img" aria-label="wiring diagram">',
             '<defs><marker id="a" markerWidth="8" markerHeight="8" refX="7" refY="4" orient="auto">'
             '<path d="M0,0 L8,4 L0,8 z"/></marker></defs>']
    for x, title, note in boxes:
        parts.append(f'<rect x="{x}" y="40" width="170" height="70" fill="#eef" stroke="#333"/>'
                     f'<text x="{x + 85}" y="70" text-anchor="middle" font-weight="bold">'
                     f'{html.escape(title)}</text>'
                     f'<text x="{x + 85}" y="92" text-anchor="middle">{html.escape(note)}</text>')
    arrows = [(190, 250, html.escape(yds)), (420, 480, "v"), (650, 710, "uf")]
    for x1, x2, label in arrows:
        parts.append(f'<line x1="{x1}" y1="75" x2="{x2}" y2="75" stroke="#333" marker-end="url(#a)"/>'
                     f'<text x="{(x1 + x2) // 2}" y="32" text-anchor="middle">{label}</text>')
    parts.append('<polyline points="795,110 795,170 335,170 335,112" fill="none" stroke="#333" '
                 'marker-end="url(#a)"/>'
                 f'<text x="565" y="190" text-anchor="middle">{html.escape(states)} '
                 "(the plant's states)</text>"
                 '<polyline points="760,110 760,150 565,150 565,112" fill="none" stroke="#999" '
                 'stroke-dasharray="4 3" marker-end="url(#a)"/>'
                 '<text x="662" y="142" text-anchor="middle" fill="#666">x1, x2 (the fault model)</text>')
    parts.append("</svg>")
    return "\n".join(parts)


def _range(v: dict[str, str]) -> str:
    low, high = v["min"], v["max"]
    if low and high:
        return f"[{low}, {high}]"
    return f"&ge; {low}" if low else (f"&le; {high}" if high else "")


def controller_documentation(model: str, xml: bytes) -> dict[str, bytes]:
    """``documentation/index.html`` and ``documentation/_main.html`` of the controller FMU ``model``
    (empty for other FMUs), from its model description ``xml``. ValueError for a variable this module
    does not describe."""
    orders = {controller_model(n): n for n in ORDERS}
    if model not in orders:
        return {}
    n = orders[model]
    variables = _variables(xml)
    unknown = [v["name"] for v in variables
               if (v["causality"] == "parameter" and _base(v["name"]) not in PARAMETERS)
               or (v["causality"] == "output" and _base(v["name"]) not in OUTPUTS)]
    if unknown:
        raise ValueError(f"{model}: documentation/index.html describes no {', '.join(unknown)} "
                         "(add it to fmu_src/toolchain/controller_doc.py)")
    e = html.escape
    inputs = [[f"<code>{e(v['name'])}</code>", e(v["description"]),
               "a measured plant state" if v["name"].startswith("x") else
               f"yd's derivative of order {DERIVATIVES.index(v['name'])}, at the same instant as yd"
               if v["name"] != "yd" else "the reference the output y = x1 must follow"]
              for v in variables if v["causality"] == "input"]
    outputs = [[f"<code>{e(v['name'])}</code>", e(v["description"]), e(OUTPUTS[_base(v["name"])][0]),
                OUTPUTS[_base(v["name"])][1]] for v in variables if v["causality"] == "output"]
    parameters = []
    for v in variables:
        if v["causality"] != "parameter":
            continue
        meaning, equation, allowed = PARAMETERS[_base(v["name"])]
        parameters.append([f"<code>{e(v['name'])}</code>", e(v["type"]), e(v["start"]), e(v["unit"]),
                           e(v["description"]) + "<br>" + e(meaning), e(equation), e(allowed),
                           _range(v)])
    code = e(example_code(n))
    yds = ", ".join(DERIVATIVES[: n + 1])
    description, _, _, _ = WORKED_EXAMPLES[n]
    page = f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>{e(model)}: the fixed-time controller for a plant of order {n}</title>
<style>body{{font-family:sans-serif;max-width:72em;margin:2em auto;line-height:1.45}}
table{{border-collapse:collapse;margin:1em 0}}
td,th{{border:1px solid #bbb;padding:.25em .5em;vertical-align:top}}
th{{background:#eee}}pre{{background:#f6f6f6;padding:1em;overflow-x:auto}}code{{font-size:95%}}</style></head>
<body>
<h1>{e(model)}</h1>
<p>The adaptive fixed-time neural-network backstepping controller of the paper {e(PAPER)}, as an FMI
Co-Simulation FMU for a plant of order <b>n = {n}</b>. There is one FMU per order
(<code>FixedTimeController1</code>, <code>FixedTimeController</code> for n = 2,
<code>FixedTimeController3</code>, <code>FixedTimeController4</code>): pick the one of your plant's order.
This page is written from the FMU's own model description when the FMU is built.</p>

<h2>The plant it assumes</h2>
<p>The paper's system (1), a nonstrict-feedback plant of order n with unknown smooth f_i and g_i:</p>
<pre>x_i' = g_i(x_1..x_i) x_(i+1) + f_i(x) + phi_i(x, z, t) + d_i(t),   i = 1..n-1
x_n' = g_n(x_1..x_n) uf + f_n(x) + phi_n(x, z, t) + d_n(t)
z'   = q(z, x)              (unmodeled dynamics, not measured)
y    = x_1</pre>
<ul>
<li>The states x_1..x_n are measured and fed to the controller; the output to track is y = x_1.</li>
<li>The input gains g_i are <b>positive</b> (their sign known, Assumption 3) and bounded,
0 &lt; b_m &le; g_i &le; b_M. <code>b_max</code> is such an upper bound b_M; only the semi-implicit law uses
it (a bound twice the largest gain keeps that law stable under a one-step communication delay).
If an input gain of your plant is negative, flip the sign of that state or of the input.</li>
<li>f_i, phi_i and d_i need not be known: a radial-basis-function network per step approximates them,
its weight norm estimated on line (eta_hat_i); the dynamic signal r bounds the unmodeled dynamics.</li>
<li>The actual control v may pass an actuator with a dead-zone and a fault uf = K(t) u(v) + L(t) before
the plant (the paper's eq. 2-6); the controller does not need to know them.</li>
</ul>

<h2>Inputs: how to feed them</h2>
{_table(["input", "description", "what it must be"], inputs)}
<p><b>yd and its derivatives must be consistent</b>: {e(yds)} are the exact derivatives of one smooth,
bounded reference signal (Assumption 2), all evaluated at the same communication point t. A derivative
from another signal, a finite difference or a delayed value breaks the law's error coordinates
z_i = x_i - zeta_(i-1). The project's Reference FMU gives a sine with its first four derivatives.</p>

<h2>Call order per communication step</h2>
<ol>
<li><code>fmi2SetReal</code> of every input at t: the plant states at t and yd with its derivatives at t.</li>
<li><code>fmi2GetReal</code> of <code>v</code> (and any other output): v, z_i and zeta_i are direct
feedthrough,
computed for the inputs just set (ModelStructure declares it), so a master that reads outputs after setting
inputs puts no delay in the loop.</li>
<li>Step the actuator and the plant over [t, t + h] with v held.</li>
<li><code>fmi2DoStep(t, h)</code> of this FMU: r and eta_hat advance over the same step with the inputs held
(zero-order hold).</li>
</ol>
<p>A master that delays every connection by one step (Jacobi) works with the explicit law at small steps
and with the semi-implicit law when b_max is at least twice the largest input gain.</p>

<h2>Parameters</h2>
<p>Equation numbers are the paper's. Ranges beyond the ones the FMU declares (min/max) are checked when
initialization ends: a violation fails <code>fmi2ExitInitializationMode</code> with a message naming the
parameter and its allowed range. The defaults are the paper's Example 1 gains (steps beyond 2 repeat step 2's:
the paper gives gains for n = 2 only), alpha = 1.5 and beta = 0.75 (chosen by experiment; the paper leaves
them open).</p>
{_table(PARAMETER_COLUMNS, parameters)}

<h2>Outputs</h2>
{_table(["output", "description", "meaning", "equation"], outputs)}

<h2>Discretization</h2>
<ul>
<li>The law is evaluated at each communication point and held over the step (a sampled controller). With
<code>discretization = 0</code> it is the paper's law itself; its fractional powers chatter when the step is
coarse for the gains (short bursts at 1 ms in the paper's examples). With <code>discretization = 1</code> each
step's feedback magnitude phi(|z_i|) is evaluated at the sample and its sign at the next one (Acary and
Brogliato's implicit sign): the feedback becomes min(phi(|z_i|), |z_i| / (b_max sample_time)), the paper's
law wherever one sample cannot drive z_i through zero. Set <code>sample_time</code> to the communication
step (the FMU warns once when they differ).</li>
<li>r and eta_hat are integrated by classical RK4 over each communication step with the inputs held
(<code>substeps</code> equal sub-steps), about 1e-12 relative to an adaptive solver at 1 ms.</li>
<li>The law is compiled (C, built into the FMU) and gives the same bits as the project's Python library
(<code>controller.law</code>); a step costs a few microseconds.</li>
</ul>

<h2>Wiring</h2>
{_wiring(n)}

<h2>Worked example: a plant that is not the paper's</h2>
<p>{e(description)}; yd = 0.5 sin t, the default gains, the semi-implicit law at h = 1 ms. Save it beside
<code>{e(model)}.fmu</code> and run it with Python and <code>pip install fmpy</code>; it prints the tracking
error after 5 s.</p>
<pre><code class="language-python">{code}</code></pre>
</body>
</html>
"""
    main = ('<!DOCTYPE html><html><head><meta charset="utf-8">'
            '<meta http-equiv="refresh" content="0; url=index.html">'
            f'<title>{e(model)}</title></head><body><a href="index.html">{e(model)}: documentation</a>'
            '</body></html>\n')
    return {INDEX: page.encode("utf-8"), MAIN: main.encode("utf-8")}
