"""Reference results of each FMU in the FMI cross-check style, cut out of one closed loop.

For each of the three FMUs, :func:`write_crosscheck` writes into ``<out>/<Model>/``
(the last level of the cross-check repository's ``fmus/2.0/cs/<platform>/<tool>/<version>/
<Model>`` layout):

- ``<Model>.fmu``: a copy of the FMU the reference was computed with;
- ``<Model>_in.csv``: every input of the FMU over time, exactly the values the master set
  in the closed loop;
- ``<Model>_ref.csv``: every output of the FMU at t = k h, exactly the values the master
  read from it in the closed loop;
- ``<Model>_ref.opt``: ``StartTime``, ``StopTime``, ``StepSize``, ``RelTol`` (and the optional
  ``OutputIntervalLength``), one ``Name, value`` per line, nothing else (fmpy's
  ``read_ref_opt_file`` parses every two-field line as a number);
- ``ReadMe.md``: the scenario, the parameters, the timing convention below and how to replay.

and ``<out>/crosscheck.json`` (paths, parameters that differ from the FMUs' start values,
timing convention) for programs.

CSV files follow the cross-check rules: comma separated, first line the quoted names
(``"time"`` then the FMI names exactly as in modelDescription.xml, e.g. ``"y[1]"``),
numbers unquoted as C floating point literals (Python ``repr``: the shortest text that
reads back to the same double, so values round-trip exactly), time in seconds and
increasing, no comments. For 500 steps of the paper scenario the files are 23 to 160 kB,
under the rules' 1 MB.

Timing in the loop (orchestrator.cosim.master): at step k, t = k h, the master reads the plant's
outputs (they depend on no input), sets y[k], ybar[k] (and the truth x, w, z in mode
``ideal``) on the estimator and reads its estimate of sample k (direct feedthrough), sets it
on the controller and reads u[k] (direct feedthrough), sets u[k] on plant and estimator,
then steps all three from t to t + h.

Input layout: sample and hold, one row per sample time plus one just before the next.
The value an input had over [k h, (k+1) h) is written at k h and again at (k+1) h - eps,
eps = 1e-3 h; the next value follows at (k+1) h::

    "time","u[1]","u[2]"
    0.0,u0_1,u0_2
    0.00999,u0_1,u0_2
    0.01,u1_1,u1_2
    0.01999,u1_1,u1_2
    ...

(2 N - 1 rows for N samples, times strictly increasing). Every sample time k h has exactly
one row, holding the value the master set at k h, so a reader that evaluates the table at the
communication points gets that value whatever it does with discontinuities: linear
interpolation at a tabulated time returns the tabulated value (fmpy: weights 0 and 1,
bit-exact; FMU Compliance Checker: lambda = 1). Between samples the value is constant except
for a ramp over the last eps of each step, which a fixed-step importer never samples.

The other layout the cross-check rules show (a repeated time stamp at every k h, the old
value then the new one) is ambiguous at exactly the instants that matter: fmpy's ``Input``
(fmpy 0.3.32, simulation.py) applies ``apply(t, after_event=True)`` in its co-simulation
loop and takes the row after the repeated time stamp (the right value), but the FMU
Compliance Checker (fmi2_input_reader.c: advance while t2 < t, then interpolate with
lambda = 1) takes the row before it, i.e. the previous sample's value: every input one step
late. ``write_crosscheck(..., layout="repeat")`` writes it anyway (fmpy reproduces the
reference with either). fmpy finds input events only at repeated time stamps, so the
default layout adds no communication point even for the variable-step controller; it needs
eps > 1e-9 t (fmpy's ``isclose``) to keep the two rows apart, checked with a margin.

Inputs the master never sets (the estimator's truth inputs x, w, z outside mode ``ideal``)
are written as their start value, which is what the FMU had.

Output sampling: ``<Model>_ref.csv`` holds at t = k h the output *after* the inputs of time
k h were set (the right limit, what the master read). fmpy's ``simulate_fmu`` for FMI 2.0
co-simulation records outputs right after ``fmi2DoStep(t, h)``, *before* it applies the
inputs of t + h (the FMU Compliance Checker does the same). For outputs without direct
feedthrough (the plant) that is the same value and a plain ``simulate_fmu`` run reproduces
the reference exactly. For direct-feedthrough outputs it records the left limit
g(state(t+h), input(t)): the controller's u appears one sample late, and the estimator's
estimate mixes the new prediction with the previous measurement. No input-file layout can
change that for the estimator: fmpy applies one input vector per step, which both
``fmi2DoStep(t)`` (it needs y[k], u[k]) and the following sample (it would need y[k+1]) see.
:func:`sample_after_inputs` is a ``step_finished`` callback for ``simulate_fmu`` that applies
the inputs of the new communication point and samples again, i.e. records what a master
that sets inputs before reading outputs (this project's, or any Gauss-Seidel master) sees;
with it the replay of each FMU alone reproduces its ``_ref.csv`` (see :func:`replay`).
(fmpy's own cross-check comparison, ``fmpy.cross_check.validate_result``, uses a band 20
samples wide and accepts even the one-sample-late plain replay; compare exactly instead.)

An importer that accumulates t += h instead of computing k h evaluates the input table a few
ulps off the sample times; with the default layout that changes an input by at most
(ulps / eps) times its step (about 3e-8 relative after 500 steps in a check of the
Compliance Checker's interpolation rule), with the repeated time stamp layout it can pick
either side of the step.

Parameters: the FMUs' own start values (the scenario they were built for); a ``seed``,
``mode`` or tracking law other than the built one is set by the master in initialization
mode and listed as a start value to set in ReadMe.md and crosscheck.json.
"""
from __future__ import annotations

import json
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.simulation import Input
from fmpy.util import read_csv, read_ref_opt_file

from ..cosim.master import run_system
from ..cosim.system import SystemDescription, closed_loop_system

__all__ = [
    "EPS_FRACTION",
    "LAYOUTS",
    "REL_TOL",
    "compare",
    "hold_rows",
    "replay",
    "sample_after_inputs",
    "write_crosscheck",
    "write_csv",
]

#: RelTol written into the _ref.opt files: the replay reproduces the reference to rounding
#: (the FMUs are fixed-step, exactly sampled; no solver tolerance is involved).
REL_TOL = 1e-9
#: Width of the step from one held input value to the next, as a fraction of h.
EPS_FRACTION = 1e-3
#: Input layouts: eps before each sample (default) or a repeated time stamp at each sample.
LAYOUTS = ("ramp", "repeat")

_NAME = re.compile(r"^([A-Za-z_]\w*)\[(\d+)\]$")


def _fmt(v: float) -> str:
    return repr(float(v))


def write_csv(path: Path, names: list[str], t: np.ndarray, values: np.ndarray) -> None:
    """A cross-check CSV: quoted header ``"time"`` + ``names``, one row per time."""
    for n in names:
        if any(c in n for c in ',"\n'):
            raise ValueError(f"variable name {n!r} cannot be written to a cross-check CSV")
    lines = [",".join(f'"{n}"' for n in ["time", *names])]
    for ti, row in zip(t, values):
        lines.append(",".join([_fmt(ti), *map(_fmt, row)]))
    path.write_text("\n".join(lines) + "\n")


def hold_rows(t: np.ndarray, values: np.ndarray, eps: float | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """Sample-and-hold rows: value k at t[k] and at t[k+1] - eps, value k+1 at t[k+1].

    ``eps=None``: ``EPS_FRACTION`` of the sample period. ``eps=0``: the repeated time stamp
    layout (value k at t[k] and t[k+1], then value k+1 at t[k+1]).
    """
    n = len(t)
    if n < 2:
        return t[:1], values[:1]
    h = float(t[1] - t[0])
    if eps is None:
        eps = EPS_FRACTION * h
    if eps and not (eps > 1e-8 * abs(float(t[-1])) and eps < h / 2):
        raise ValueError(f"eps = {eps} s cannot separate the rows of a hold at t = {t[-1]} s "
                         f"(fmpy merges times closer than 1e-9 t); write fewer steps")
    idx_v = np.concatenate([[0], np.column_stack([np.arange(n - 1), np.arange(1, n)]).ravel()])
    times = np.concatenate([[t[0]], np.column_stack([t[1:] - eps, t[1:]]).ravel()])
    return times, values[idx_v]


def _split(name: str) -> tuple[str, int]:
    m = _NAME.match(name)
    if m is None:
        return name, 0
    return m.group(1), int(m.group(2)) - 1


def _start_value(var) -> float:
    return float(var.start) if var.start is not None else 0.0


def _different_start_values(md, parameters: dict[str, Any]) -> dict[str, Any]:
    """Parameters the loop set to something other than the FMU's start value."""
    by_name = {v.name: v for v in md.modelVariables}
    out: dict[str, Any] = {}
    for name, value in parameters.items():
        var = by_name[name]
        if var.type == "String":
            same = var.start == str(value)
            value = str(value)
        elif var.type == "Integer":
            same = var.start is not None and int(var.start) == int(value)
            value = int(value)
        else:
            same = var.start is not None and float(var.start) == float(value)
            value = float(value)
        if not same:
            out[name] = value
    return out


def write_crosscheck(fmus: dict[str, Path], config: dict, out_dir: Path, *, steps: int = 500,
                     seed: int | None = None, mode: str | None = None,
                     layout: str = "ramp",
                     system: SystemDescription | None = None) -> dict[str, dict[str, Path]]:
    """Run the closed loop once for ``steps`` steps and write each FMU's cross-check files.

    ``fmus``: the FMUs built for ``config`` (orchestrator.workflow.build), by FMU key;
    ``system``: the co-simulation (default: the paper's loop,
    :func:`orchestrator.cosim.system.closed_loop_system`, with ``seed`` and ``mode``,
    which default to the configuration's, the FMUs' start values); ``layout``: input file
    layout, ``ramp`` (default) or ``repeat`` (see the module docstring). One reference per
    component. Returns, per component, the paths ``fmu``, ``in``, ``ref``, ``opt``,
    ``readme``.
    """
    if steps < 2:
        raise ValueError("steps must be at least 2 (StopTime must exceed StartTime)")
    if layout not in LAYOUTS:
        raise ValueError(f"layout {layout!r} is not one of {', '.join(LAYOUTS)}")
    seed = int(config["seed"] if seed is None else seed)
    mode = str(config["mode"] if mode is None else mode)
    tracking = str(config.get("tracking", "lq"))
    if system is None:
        system = closed_loop_system(dict(config, mode=mode, seed=seed, tracking=tracking))
    h = float(system.h)
    out = Path(out_dir)
    t0 = time.perf_counter()
    traces, _, _ = run_system(system, fmus, steps, instance_suffix=f"_{mode}_{seed}")
    loop_s = time.perf_counter() - t0
    t = np.arange(steps) * h
    eps = EPS_FRACTION * h if layout == "ramp" else 0.0
    trace_of = system.trace_names()
    #: (component, input scalar) -> (trace, column) of the output feeding it in the run
    fed: dict[tuple[str, str], tuple[str, int]] = {}
    for c in system.scalar_connections(active_only=True):
        base, i = _split(c.source[1])
        fed[c.target] = (trace_of[(c.source[0], base)], i)
    manifest: dict[str, Any] = {
        "h": h, "steps": steps, "seed": seed, "mode": mode, "tracking": tracking,
        "StartTime": 0.0, "StopTime": float(t[-1]), "StepSize": h, "RelTol": REL_TOL,
        "input_layout": (f"sample and hold: value k at k h and (k+1) h - {eps!r} s, value k+1 "
                         f"at (k+1) h" if eps else "sample and hold: value k at k h and "
                         "(k+1) h, value k+1 at (k+1) h (repeated time stamp)"),
        "input_eps_s": eps,
        "output_sampling": "at k h after the inputs of k h are set (right limit)",
        "cosimulation_s": loop_s, "fmus": {},
    }
    paths: dict[str, dict[str, Path]] = {}
    for comp in system.components:
        key, model = comp.name, comp.model
        md = read_model_description(str(fmus[comp.fmu]))
        d = out / model if len(system.components) == len({c.fmu for c in system.components}) \
            else out / key
        d.mkdir(parents=True, exist_ok=True)
        fmu_copy = d / f"{model}.fmu"
        if Path(fmus[comp.fmu]).resolve() != fmu_copy.resolve():
            shutil.copyfile(fmus[comp.fmu], fmu_copy)
        inputs = [v for v in md.modelVariables if v.causality == "input"]
        outputs = [v for v in md.modelVariables if v.causality == "output"]
        in_vals = np.empty((steps, len(inputs)))
        held: list[str] = []
        for j, var in enumerate(inputs):
            src = fed.get((key, var.name))
            if src is not None:
                in_vals[:, j] = traces[src[0]][:, src[1]]
            else:
                in_vals[:, j] = _start_value(var)
                held.append(var.name)
        out_vals = np.empty((steps, len(outputs)))
        for j, var in enumerate(outputs):
            base, i = _split(var.name)
            out_vals[:, j] = traces[trace_of[(key, base)]][:, i]
        p = {"fmu": fmu_copy, "in": d / f"{model}_in.csv", "ref": d / f"{model}_ref.csv",
             "opt": d / f"{model}_ref.opt", "readme": d / "ReadMe.md"}
        ti, vi = hold_rows(t, in_vals, eps)
        write_csv(p["in"], [v.name for v in inputs], ti, vi)
        write_csv(p["ref"], [v.name for v in outputs], t, out_vals)
        p["opt"].write_text(f"StartTime, {_fmt(0.0)}\nStopTime, {_fmt(t[-1])}\n"
                            f"StepSize, {_fmt(h)}\nRelTol, {_fmt(REL_TOL)}\n"
                            f"OutputIntervalLength, {_fmt(h)}\n")
        start_values = _different_start_values(md, dict(comp.parameters))
        deps = {u.variable.name: u.dependencies or [] for u in md.outputs}
        feedthrough = [v.name for v in outputs
                       if any(dv.causality == "input" for dv in deps.get(v.name, []))]
        p["readme"].write_text(_readme(model, key, md, steps, h, seed, mode, tracking,
                                       start_values, held, feedthrough, eps))
        paths[key] = p
        manifest["fmus"][key] = {
            "model": model, **{k: str(v) for k, v in p.items()},
            "start_values": start_values, "inputs_held_at_start_value": held,
            "direct_feedthrough_outputs": feedthrough,
            "bytes": {k: v.stat().st_size for k, v in p.items()},
        }
    (out / "crosscheck.json").write_text(json.dumps(manifest, indent=2))
    return paths


def _readme(model, key, md, steps, h, seed, mode, tracking, start_values, held, feedthrough,
            eps) -> str:
    sv = ("none: the FMU's start values are the ones used" if not start_values else
          ", ".join(f"`{k}` = `{v}`" for k, v in start_values.items()))
    lines = [
        f"# {model}: cross-check reference ({key})", "",
        f"{md.description or ''}", "",
        f"Generated by `orchestrator.interop.crosscheck.write_crosscheck` from one closed-loop "
        f"co-simulation of plant, estimator and controller (fmpy master, "
        f"`orchestrator.cosim.master.run_system`): {steps} samples, h = {h} s, "
        f"seed {seed}, estimator mode `{mode}`, tracking law `{tracking}`.", "",
        f"Parameters: start values of this FMU's modelDescription.xml (the scenario it was "
        f"built for). Start values to set before replaying: {sv}.", "",
        (f"- `{model}_in.csv`: the inputs the master set, sample and hold: the value set at "
         f"k h is written at k h and at (k+1) h - {eps!r} s, the next one at (k+1) h; every "
         f"sample time has one row, so evaluating the table at k h (with linear "
         f"interpolation) gives the value set at k h." if eps else
         f"- `{model}_in.csv`: the inputs the master set, sample and hold: each value at k h "
         f"and again at (k+1) h, then the next value at (k+1) h (a repeated time stamp is "
         f"the step; take the value after it at k h)."),
        f"- `{model}_ref.csv`: the outputs the master read at t = k h, k = 0..{steps - 1}, "
        f"after setting the inputs of k h.",
        f"- `{model}_ref.opt`: StartTime, StopTime, StepSize (= the FMU's sample period h; "
        f"communication step and output interval), RelTol.",
    ]
    if held:
        lines.append(f"- Inputs the master did not connect (held at their start value): "
                     f"{', '.join(f'`{n}`' for n in held)}.")
    lines.append("")
    if feedthrough:
        lines += [
            f"Direct feedthrough: {', '.join(f'`{n}`' for n in feedthrough)} depend on the "
            f"inputs of the same instant. Sample them after setting the inputs of the "
            f"communication point. fmpy's `simulate_fmu` samples after `fmi2DoStep` and before "
            f"setting the next inputs (the left limit); replay with the `step_finished` callback "
            f"`orchestrator.interop.crosscheck.sample_after_inputs` (or `orchestrator.interop.crosscheck.replay`), "
            f"which sets the inputs of the new communication point and samples again.", ""]
    else:
        lines += ["No output depends directly on an input: `fmpy.simulate_fmu(fmu, "
                  "input=read_csv(in), start_time, stop_time, output_interval=StepSize)` "
                  "reproduces the reference as it is.", ""]
    return "\n".join(lines)


def sample_after_inputs(signals: np.ndarray | None, model_description) -> Callable[[float, Any], bool]:
    """A ``step_finished`` callback for ``fmpy.simulate_fmu`` (FMI 2.0 co-simulation):
    after each step, apply the inputs of the new communication point (after its event) and
    replace the sample fmpy just recorded by one taken with those inputs set."""
    state: dict[str, Any] = {}

    def step_finished(time: float, recorder) -> bool:
        if signals is None:
            return True
        inp = state.get("input")
        if inp is None:
            inp = state["input"] = Input(recorder.fmu, model_description, signals)
        inp.apply(time, after_event=True)
        recorder.rows.pop()
        recorder.sample(time)
        return True

    return step_finished


def replay(fmu: Path, opt: Path, in_csv: Path | None, outputs: list[str], *,
           start_values: dict[str, Any] | None = None,
           sample_after_input: bool = True) -> np.ndarray:
    """Simulate one FMU alone with fmpy from its cross-check files.

    ``sample_after_input=False`` is fmpy's own sampling (outputs recorded before the next
    inputs are set). Returns fmpy's structured result array (``time`` + ``outputs``).
    """
    opts = read_ref_opt_file(str(opt))
    signals = read_csv(str(in_csv)) if in_csv is not None else None
    md = read_model_description(str(fmu))
    return simulate_fmu(
        str(fmu), start_time=opts["StartTime"], stop_time=opts["StopTime"],
        output_interval=opts["StepSize"], relative_tolerance=opts["RelTol"],
        input=signals, output=list(outputs), start_values=dict(start_values or {}),
        model_description=md,
        step_finished=sample_after_inputs(signals, md) if sample_after_input else None)


def compare(result: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Max |result - reference| per reference column (same time grid required)."""
    if len(result) != len(reference) or not np.array_equal(result["time"], reference["time"]):
        raise ValueError(f"time grids differ ({len(result)} vs {len(reference)} rows)")
    return {n: float(np.max(np.abs(result[n] - reference[n])))
            for n in reference.dtype.names[1:]}
