"""Reference results of each FMU in the FMI cross-check style, cut out of one closed loop.

:func:`write_crosscheck` runs the loop once and writes, per FMU, ``<Model>.fmu``,
``<Model>_in.csv`` (inputs as held values), ``<Model>_ref.csv`` (outputs as the master read
them), ``<Model>_ref.opt`` and ``ReadMe.md``, plus ``crosscheck.json``; :func:`replay` and
:func:`sample_after_inputs` replay one FMU alone with fmpy, :func:`compare` checks it.
The file layout, the timing convention, the two input layouts (``ramp``, ``repeat``) and
why direct-feedthrough outputs need :func:`sample_after_inputs`: docs/crosscheck.md.
"""
from __future__ import annotations

import json
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.simulation import Input
from fmpy.util import read_csv, read_ref_opt_file

from ..cosim.master import run_system
from ..cosim.system import SystemDescription, closed_loop_system

if TYPE_CHECKING:
    from fmpy.model_description import ModelDescription, ModelVariable
    from fmpy.simulation import Recorder

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
    """A cross-check CSV: quoted header ``"time"`` + ``names``, one row per time.

    Parameters
    ----------
    path : Path
        The file to write.
    names : list[str]
        Column names after ``time``.
    t : np.ndarray
        Times, s, shape (K,).
    values : np.ndarray
        Values, shape (K, len(names)); written as Python's repr of each double.

    Raises
    ------
    ValueError
        If a name contains a comma, a double quote or a newline.
    """
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

    Parameters
    ----------
    t : np.ndarray
        Sample times, s, shape (K,), equally spaced by h.
    values : np.ndarray
        Values per sample, shape (K, ...).
    eps : float or None, optional
        Width of the step, s: None gives ``EPS_FRACTION`` h; 0 gives the repeated time
        stamp layout (value k at t[k] and t[k+1], then value k+1 at t[k+1]).

    Returns
    -------
    times : np.ndarray
        Row times, shape (2 K - 1,) (K < 2: the first sample only).
    rows : np.ndarray
        Row values, shape (2 K - 1, ...).

    Raises
    ------
    ValueError
        If eps cannot separate the rows (too small against t[-1], or not below h / 2).
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


def _start_value(var: ModelVariable) -> float:
    return float(var.start) if var.start is not None else 0.0


def _different_start_values(md: ModelDescription, parameters: dict[str, Any]) -> dict[str, Any]:
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

    One reference per component; ``crosscheck.json`` in ``out_dir`` describes the run.

    Parameters
    ----------
    fmus : dict[str, Path]
        The FMUs built for ``config`` (orchestrator.running.build), by FMU key.
    config : dict
        The FMUs' configuration (:func:`orchestrator.cosim.build.fmu_config`).
    out_dir : Path
        Destination folder (a subfolder per FMU).
    steps : int, optional
        Number of samples (at least 2).
    seed : int or None, optional
        Seed of the plant's noise; default the configuration's (the FMU's start value).
    mode : str or None, optional
        Estimator mode; default the configuration's.
    layout : str, optional
        Input file layout, ``ramp`` (default) or ``repeat`` (see docs/crosscheck.md).
    system : SystemDescription or None, optional
        The co-simulation (default: the paper's loop,
        :func:`orchestrator.cosim.system.closed_loop_system`, with ``seed`` and ``mode``).

    Returns
    -------
    dict[str, dict[str, Path]]
        Per component, the paths ``fmu``, ``in``, ``ref``, ``opt``, ``readme``.

    Raises
    ------
    ValueError
        If ``steps`` < 2 or the layout is unknown.
    CosimError
        If the co-simulation fails.
    """
    if steps < 2:
        raise ValueError("steps must be at least 2 (StopTime must exceed StartTime)")
    if layout not in LAYOUTS:
        raise ValueError(f"layout {layout!r} is not one of {', '.join(LAYOUTS)}")
    seed = int(config["seed"] if seed is None else seed)
    mode = str(config["estimator"] if mode is None else mode)
    tracking = str(config.get("tracking", "lq"))
    if system is None:
        system = closed_loop_system(dict(config, estimator=mode, seed=seed, tracking=tracking))
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


def _readme(model: str, key: str, md: ModelDescription, steps: int, h: float, seed: int,
            mode: str, tracking: str, start_values: dict[str, Any], held: list[str],
            feedthrough: list[str], eps: float) -> str:
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
            f"`orchestrator.interop.crosscheck.sample_after_inputs` (or "
            f"`orchestrator.interop.crosscheck.replay`), "
            f"which sets the inputs of the new communication point and samples again.", ""]
    else:
        lines += ["No output depends directly on an input: `fmpy.simulate_fmu(fmu, "
                  "input=read_csv(in), start_time, stop_time, output_interval=StepSize)` "
                  "reproduces the reference as it is.", ""]
    return "\n".join(lines)


def sample_after_inputs(signals: np.ndarray | None, model_description: ModelDescription
                        ) -> Callable[[float, Any], bool]:
    """A ``step_finished`` callback for ``fmpy.simulate_fmu`` (FMI 2.0 co-simulation).

    After each step, apply the inputs of the new communication point (after its event) and
    replace the sample fmpy just recorded by one taken with those inputs set.

    Parameters
    ----------
    signals : np.ndarray or None
        The input table (``fmpy.util.read_csv`` of the ``_in.csv``); None: no inputs, the
        callback changes nothing.
    model_description : ModelDescription
        The FMU's model description (fmpy).

    Returns
    -------
    Callable[[float, Any], bool]
        ``step_finished(time, recorder)``, always True (continue).
    """
    state: dict[str, Any] = {}

    def step_finished(time: float, recorder: Recorder) -> bool:
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

    Parameters
    ----------
    fmu : Path
        The FMU.
    opt : Path
        Its ``_ref.opt`` (StartTime, StopTime, StepSize, RelTol).
    in_csv : Path or None
        Its ``_in.csv``, or None for an FMU without inputs.
    outputs : list[str]
        The outputs to record.
    start_values : dict[str, Any] or None, optional
        Start values to set before the replay.
    sample_after_input : bool, optional
        Sample after setting the inputs of each communication point
        (:func:`sample_after_inputs`); False is fmpy's own sampling (outputs recorded
        before the next inputs are set).

    Returns
    -------
    np.ndarray
        fmpy's structured result array (``time`` + ``outputs``).
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
    """Max |result - reference| per reference column (same time grid required).

    Parameters
    ----------
    result : np.ndarray
        Structured array with a ``time`` field (:func:`replay`).
    reference : np.ndarray
        Structured array read from the ``_ref.csv``.

    Returns
    -------
    dict[str, float]
        Column name -> maximum absolute difference.

    Raises
    ------
    ValueError
        If the time grids differ.
    """
    if len(result) != len(reference) or not np.array_equal(result["time"], reference["time"]):
        raise ValueError(f"time grids differ ({len(result)} vs {len(reference)} rows)")
    return {n: float(np.max(np.abs(result[n] - reference[n])))
            for n in reference.dtype.names[1:]}
