"""Vehicle FMUs the tests make from models the project does not otherwise hold, as a user
would bring them (``[vehicles] model = "fmu"``):

- :func:`mass_damper_fmu`: a 3-axis mass-damper in C, M_a v_a' = F_a - D_a v_a, n_a' = v_a,
  compiled here into a co-simulation FMU (its own FMI functions, libc and libm only; exact
  steps with the force held: v+ = a v + (1 - a) F / D, a = exp(-D h / M)). Its M, D are the
  identification's independent reference.
- :func:`torpedo_fmu`: docs/examples/torpedo.py (Prestero's REMUS-like torpedo, numpy only)
  with its PID speed / heading / depth autopilot, packaged with pythonfmu: set-point inputs.
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
import uuid
import zipfile
from pathlib import Path

from orchestrator.cosim.native_build import FMI_HEADERS, _fmi_include, compiler

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "docs" / "examples"

_C = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"
/* value references: 0-2 F (in), 3-5 n e d (out), 6-8 v_n v_e v_d (out),
   9-11 M, 12-14 D, 15-17 n0, 18-20 v0 (parameters) */
#define NV 21
typedef struct { double r[NV]; double t; } Inst;
static const double START[NV] = {0,0,0, 0,0,0, 0,0,0, %(M)s, %(D)s, 0,0,20, 0,0,0};
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean l, size_t n,
                               const fmi2String cat[]) { return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String res, const fmi2CallbackFunctions *f,
                              fmi2Boolean vis, fmi2Boolean log) {
  if (type != fmi2CoSimulation || strcmp(guid, "%(guid)s") != 0) return NULL;
  Inst *s = calloc(1, sizeof(Inst));
  if (s) memcpy(s->r, START, sizeof START);
  return s;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol,
                               fmi2Real t0, fmi2Boolean sd, fmi2Real t1) {
  ((Inst *)c)->t = t0; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
  Inst *s = c;
  for (int a = 0; a < 3; a++) {
    if (!(s->r[9 + a] > 0) || !(s->r[12 + a] > 0)) return fmi2Error;
    s->r[3 + a] = s->r[15 + a]; s->r[6 + a] = s->r[18 + a];
  }
  return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { memcpy(((Inst *)c)->r, START, sizeof START);
  return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       fmi2Real v[]) {
  for (size_t i = 0; i < n; i++) { if (vr[i] >= NV) return fmi2Error;
    v[i] = ((Inst *)c)->r[vr[i]]; }
  return fmi2OK; }
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
  for (size_t i = 0; i < n; i++) { if (vr[i] >= NV || (vr[i] >= 3 && vr[i] < 9))
    return fmi2Error; ((Inst *)c)->r[vr[i]] = v[i]; }
  return fmi2OK; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean nsp) {
  Inst *s = c;
  for (int a = 0; a < 3; a++) {
    double M = s->r[9 + a], D = s->r[12 + a], F = s->r[a], v = s->r[6 + a];
    double al = exp(-D * h / M), vi = F / D;
    s->r[3 + a] += vi * h + (v - vi) * (M / D) * (1.0 - al);
    s->r[6 + a] = al * v + (1.0 - al) * vi;
  }
  s->t = t + h;
  return fmi2OK;
}
#define NO(decl) decl { return fmi2Error; }
NO(fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]))
NO(fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]))
NO(fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]))
NO(fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]))
NO(fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]))
NO(fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]))
NO(fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s))
NO(fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s))
NO(fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s))
NO(fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n))
NO(fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n))
NO(fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s))
NO(fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na, const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real df[]))
NO(fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]))
NO(fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]))
NO(fmi2Status fmi2CancelStep(fmi2Component c))
NO(fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v))
NO(fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v))
NO(fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v))
NO(fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v))
NO(fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v))
"""

_NAMES = (["F_n", "F_e", "F_d"], ["n", "e", "d"], ["v_n", "v_e", "v_d"],
          ["M_n", "M_e", "M_d"], ["D_n", "D_e", "D_d"], ["n0", "e0", "d0"],
          ["vn0", "ve0", "vd0"])


def _model_description(guid: str, M: tuple[float, ...], D: tuple[float, ...]) -> str:
    rows, vr = [], 0
    starts = [[0.0] * 3, None, None, list(M), list(D), [0.0, 0.0, 20.0], [0.0] * 3]
    for group, names in enumerate(_NAMES):
        for k, name in enumerate(names):
            if group == 0:
                attrs, real = 'causality="input" variability="continuous"', \
                    f'<Real start="{starts[0][k]}"/>'
            elif group in (1, 2):
                attrs, real = ('causality="output" variability="continuous" '
                               'initial="exact"'), '<Real start="0"/>'
            else:
                attrs, real = ('causality="parameter" variability="fixed"',
                               f'<Real start="{starts[group][k]!r}"/>')
            rows.append(f'    <ScalarVariable name="{name}" valueReference="{vr}" {attrs}>'
                        f'{real}</ScalarVariable>')
            vr += 1
    outs = "\n".join(f'      <Unknown index="{i}"/>' for i in range(4, 10))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="MassDamper" guid="{guid}"
  generationTool="tests/support/vehicle_fmus.py (hand-written C)" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="MassDamper" canHandleVariableCommunicationStepSize="true"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{outs}
    </Outputs>
  </ModelStructure>
</fmiModelDescription>
"""


def mass_damper_fmu(out: Path, M: tuple[float, float, float] = (50.0, 60.0, 70.0),
                    D: tuple[float, float, float] = (10.0, 20.0, 30.0)) -> Path:
    """``out/MassDamper.fmu``: the C mass-damper with these M (kg) and D (kg/s) per NED
    axis. Variables: inputs F_n, F_e, F_d (N); outputs n, e, d (m), v_n, v_e, v_d (m/s);
    parameters M_*, D_*, start n0, e0, d0 (m), vn0, ve0, vd0 (m/s)."""
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, f"massdamper{M}{D}")) + "}"
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        (t / "model.c").write_text(_C % {"M": ", ".join(map(repr, M)),
                                         "D": ", ".join(map(repr, D)), "guid": guid})
        for name in FMI_HEADERS:
            shutil.copy2(_fmi_include() / name, t / name)
        lib = t / "MassDamper.so"
        subprocess.run([compiler(), "-O2", "-shared", "-fPIC", "-I", str(t), "-o", str(lib),
                        str(t / "model.c"), "-lm"], check=True, capture_output=True)
        fmu = out / "MassDamper.fmu"
        with zipfile.ZipFile(fmu, "w") as z:
            z.writestr("modelDescription.xml", _model_description(guid, M, D))
            z.write(lib, "binaries/linux64/MassDamper.so")
            z.write(t / "model.c", "sources/model.c")
    return fmu


_TORPEDO_SLAVE = '''
"""docs/examples/torpedo.py's torpedo and PID autopilot as a set-point FMU."""
import math
import numpy as np
from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real
from torpedo import PidAutopilot, Torpedo


class FeedForwardAutopilot(PidAutopilot):
    """The example's PID autopilot with the depth rate fed forward: the pitch that makes
    d' = -u sin(theta) equal the commanded depth rate is added to its depth loop's pitch
    (as a vehicle's autopilot that takes rate set-points does)."""

    def command(self, setpoint, sensors, h):
        U_d, psi_d, d_d, dd_d = setpoint
        u = max(float(sensors[0]), 0.5)
        ff = math.asin(min(max(-dd_d / u, -0.34), 0.34))        # at most 20 deg
        rudder, stern, rpm = super().command([U_d, psi_d, d_d], sensors, h)
        return [rudder, stern - 2.0 * ff, rpm]


class TorpedoSetpoint(Fmi2Slave):
    author = "auv-cosim tests"
    description = "Prestero REMUS-like torpedo with a PID speed/heading/depth autopilot"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.U_d, self.psi_d, self.d_d, self.dd_d = 1.5, 0.0, 20.0, 0.0
        self.n0, self.e0, self.d0, self.vn0, self.ve0, self.vd0 = 0.0, 0.0, 20.0, 1.5, 0.0, 0.0
        self.out = [0.0] * 6
        self.car = None
        for name in ("U_d", "psi_d", "d_d", "dd_d"):
            self.register_variable(Real(name, causality=Fmi2Causality.input))
        for name in ("n0", "e0", "d0", "vn0", "ve0", "vd0"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter,
                                        variability=Fmi2Variability.fixed))
        for k, name in enumerate(("n", "e", "d", "v_n", "v_e", "v_d")):
            self.register_variable(Real(name, causality=Fmi2Causality.output,
                                        getter=lambda k=k: self.out[k]))

    def _read(self):
        s = self.car.s
        th, ps, u, v, w = s[3], s[4], s[5], s[6], s[7]
        vel = [math.cos(ps) * math.cos(th) * u - math.sin(ps) * v
               + math.cos(ps) * math.sin(th) * w,
               math.sin(ps) * math.cos(th) * u + math.cos(ps) * v
               + math.sin(ps) * math.sin(th) * w, -math.sin(th) * u + math.cos(th) * w]
        self.out = [float(x) for x in (*s[:3], *vel)]

    def exit_initialization_mode(self):
        self.car = Torpedo([self.n0, self.e0, self.d0], [self.vn0, self.ve0, self.vd0],
                           [0.0, 0.0, 0.0], fix_sigma=0.0)
        self.pid = FeedForwardAutopilot()
        self._read()

    def do_step(self, t, h):
        cmd = self.pid.command([self.U_d, self.psi_d, self.d_d, self.dd_d],
                               self.car.sensors(), h)
        self.car.step(cmd, h)
        self._read()
        return True
'''


def torpedo_fmu(out: Path) -> Path:
    """``out/TorpedoSetpoint.fmu``: the example torpedo with its PID autopilot (pythonfmu),
    the depth rate fed forward. Inputs U_d (m/s), psi_d (rad), d_d (m), dd_d (m/s); outputs n, e, d (m), v_n, v_e, v_d (m/s, over
    ground, no current); parameters n0, e0, d0, vn0, ve0, vd0 (start)."""
    import sys

    from pythonfmu.builder import FmuBuilder
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "torpedo_setpoint_slave.py"
        script.write_text(_TORPEDO_SLAVE)
        sys.path.insert(0, str(EXAMPLES))         # the build imports the slave
        try:
            fmu = FmuBuilder.build_FMU(script, dest=out,
                                       project_files=[EXAMPLES / "torpedo.py"])
        finally:
            sys.path.remove(str(EXAMPLES))
            sys.modules.pop("torpedo_setpoint_slave", None)
    return Path(fmu)
