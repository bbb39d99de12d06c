"""What the CLI commands do: build FMUs, run and compare estimators, write outputs."""
from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from estimator_fmu.estimators import make_estimator
from plant_model.discretization import discretize
from plant_model.linalg_checks import ModelError

from .analysis.formation import formation_summary
from .analysis.full_information import fleet_bound, fleet_comparison
from .analysis.prediction import method_predictions
from .analysis.summary import (
    method_summary,
    run_stats,
    stationarity_note,
    versions,
)
from .analysis.tracking_segments import run_segments, segment_summary
from .atomic import write_text_atomically
from .cosim.build import build_fmus, fmu_config, variables_markdown
from .cosim.master import run_cosimulation
from .cosim.system import SystemDescription, closed_loop_system
from .interrupt import StopFlag, stop_on_signals
from .memory import check_memory
from .outputs import file_stem
from .scenario import Scenario

if TYPE_CHECKING:
    from .recording import FleetLayout

__all__ = ["scenario_config", "scenario_system", "build", "simulate", "write_fmu_readme",
           "method_list", "check_memory",
           "fleet_layout", "record_stride"]

FMU_README_HEAD = """# FMUs

`auv-cosim build` writes the three FMI 2.0 co-simulation FMUs here (the `.fmu` files are
not committed; build them). They are built with pythonfmu for one scenario: its
dimensions fix the number of variables, its values are the start values. Whatever a host
sets in initialization mode is used: the plant discretizes, the estimator designs its
filters and the controller solves its Riccati and Sylvester equations in
exitInitializationMode.

Importing them needs a Python interpreter in the host process: pythonfmu's binary embeds
the host's Python (fmpy and libcosimpy run the FMU in their own interpreter; a non-Python
host must load libpython, see the README), so each FMU declares
`needsExecutionTool="true"`. What each FMU's code imports from that Python:

| FMU | needs |
|---|---|
| `AuvPlant` | Python 3.11+, numpy, scipy (matrix exponential, Van Loan); networkx for fleet FMUs |
| `AuvEstimator` | Python 3.11+, numpy, scipy (discrete Riccati equation); networkx for fleet FMUs |
| `AuvController` | Python 3.11+, numpy, scipy (Riccati, Sylvester); networkx for fleet FMUs |
| `AuvNetwork` (per-vehicle fleets over acoustic links, docs/network.md) | Python 3.11+, numpy |
| `AuvRemus6dof` (nonlinear REMUS 100) | Python 3.11+, numpy, scipy; numba if present |

pythonfmu itself and this project's modules travel inside each FMU (`resources/`).
All three support fmi2Get/SetFMUstate and fmi2Serialize/DeSerializeFMUstate.

Fleet FMUs do not expose the stacked matrices (they grow as (N p)^2) but the quantities
a user changes: `vehicle[i].mass`, `vehicle[i].added_mass[k]`, `vehicle[i].offset[k]`,
`vehicle[i].x0[k]`, `vehicle[i].current.time_constant`, `vehicle[i].current.sigma`,
`vehicle[i].W_x`, `vehicle[i].V_y`, `vehicle[i].Q`, `vehicle[i].R`, `a[i,j]` (weight of the
edge j -> i, only for edges that exist), `a0[i]` (pinning), `coupling[a,b]`, `leader.F`,
`leader.H`, `leader.z0`, `leader.W_z`; each FMU exposes only what its mathematics reads.
The controller's String parameter `tracking` chooses `lq` (the paper) or `regulator`.

Conventions: FMI structured names (`A[1,2]` is row 1, column 2), SI units where a
quantity has one (the paper's example is dimensionless apart from time), every variable
has a description. Outputs with direct feedthrough declare it in ModelStructure: the
estimator's estimates depend on y, ybar (and the truth inputs, read only in mode `ideal`),
the controller's u on the estimates; the plant's outputs depend on no input.

Errors: a design that cannot exist or a bad parameter makes exitInitializationMode fail
(pythonfmu reports every Python exception as fmi2Fatal) with a logged message naming the
problem; a NaN or infinite input is logged when set and the next fmi2DoStep returns
fmi2Discard, naming the input. Plant and estimator accept only the communication step
`h` they were set up for (`canHandleVariableCommunicationStepSize="false"`).

The per-vehicle deployment (`auv-cosim build --deployment per-vehicle`) builds other FMUs
instead: `AuvLeader`, `AuvVehicle`, `AuvVehicleEstimator` and `AuvVehicleController`
(distributed) or `AuvCentralController` (centralized), one per kind for every vehicle;
`docs/per-vehicle.md` lists their variables and wiring. A vehicle of model
`remus100-6dof` is an `AuvRemus6dof` in place of `AuvVehicle`: the same input `u` and
outputs `y`, `x`, `w`, plus `attitude`, `rpm`, `rudder`, `stern` and `saturated`; with
`[sensors] kind = "remus"` both vehicle FMUs also output `nav` (acoustic fix, DVL, depth,
valid flags), which the estimator reads in place of `y`.

Native FMUs, no Python needed (`auv-cosim export native`, docs/native.md): once designed,
every FMU but `AuvNetwork` is a linear system, y = C q + D u + c + G xi and
q+ = A q + B u + Bo y + b + F xi. The export compiles it from one C99 file
(`AuvControllerNative`, `AuvEstimatorNative`, `AuvPlantNative`, and per vehicle
`AuvLeaderNative`, `AuvVehicleNative`, `AuvVehicleEstimatorNative`,
`AuvVehicleControllerNative`, `AuvCentralControllerNative`), with the same inputs, outputs
and direct-feedthrough declarations, `needsExecutionTool="false"`, the sources in
`sources/` and a `binaries/linux64` library that needs only libc and libm. Its parameters
are the designed matrices (`Ks`, `Ce`, `Dm`, `Aq`, `Bu`, `Ad`, `Bd`, `Lq`, `Lr`, ...), not
the model: a native FMU does not solve the Riccati equations again, so a design change
means exporting again or setting those parameters. The native plant draws numpy's
normals in C (PCG64 and numpy's ziggurat, seeded from `seed`, and a vehicle's `stream`,
like numpy's SeedSequence), so native and pythonfmu runs of a seed agree. A bad parameter
gives fmi2Error with a logged message naming the variable; state get/set/serialize are
supported.

Below: the variables for the built-in `{scenario}` scenario (generated by `auv-cosim build`).

"""


def scenario_config(sc: Scenario) -> dict[str, Any]:
    """The FMU configuration of a scenario: dimensions, start values, h, T, seed, mode.

    Parameters
    ----------
    sc : Scenario
        A validated scenario with its run settings.

    Returns
    -------
    dict
        JSON-ready configuration the three FMUs are built with
        (:func:`orchestrator.cosim.build.fmu_config`).
    """
    return fmu_config(sc.system.to_mapping(), sc.system.dims, sc.h, sc.T, sc.seed, sc.estimator,
                      sc.tracking, sc.fleet)


def scenario_system(sc: Scenario) -> SystemDescription:
    """The system description of a scenario with its run settings (seed, estimator mode,
    tracking law): what the master runs and the exports write.

    Parameters
    ----------
    sc : Scenario
        A validated scenario.

    Returns
    -------
    SystemDescription
        The paper's loop of plant, estimator and controller, named after the scenario; for
        ``deployment = "per-vehicle"`` the leader and one vehicle, estimator and controller
        per AUV (:mod:`orchestrator.cosim.per_vehicle`) in the scenario's architecture.
    """
    if sc.deployment == "per-vehicle":
        from .per_vehicle_run import PerVehicleRuns
        return PerVehicleRuns(sc, Path(".")).system(sc.architecture, sc.estimator,
                                                    sc.tracking, sc.seed)
    return closed_loop_system(scenario_config(sc), name=sc.name)


def write_fmu_readme(sc: Scenario, path: Path) -> None:
    """Write ``fmus/README.md``: what the FMUs need, and every variable of the FMUs built for
    ``sc`` (name, causality, variability, unit, start, description).

    Parameters
    ----------
    sc : Scenario
        The scenario the variable tables are generated for.
    path : Path
        The file to write.
    """
    path.write_text(FMU_README_HEAD.format(scenario=sc.name)
                    + variables_markdown(scenario_config(sc)))


def build(sc: Scenario, out_dir: Path | str) -> dict[str, Path]:
    """The three FMUs of a scenario in ``out_dir`` (taken from the FMU cache when an
    identical build exists).

    Parameters
    ----------
    sc : Scenario
        The scenario; its values are the FMUs' start values.
    out_dir : Path or str
        Folder for ``AuvPlant.fmu``, ``AuvEstimator.fmu``, ``AuvController.fmu``.

    Returns
    -------
    dict
        FMU key (plant, estimator, controller) -> path.
    """
    if sc.deployment == "per-vehicle":
        from .per_vehicle_run import PerVehicleRuns
        return PerVehicleRuns(sc, Path(out_dir)).fmus(sc.architecture)
    return build_fmus(scenario_config(sc), Path(out_dir))


#: the prediction of a fleet of nonlinear vehicles is the linear design model's
NONLINEAR_NOTE = ("predicted on the linear design model: the vehicles are the nonlinear "
                  "remus100-6dof, so simulation and prediction differ by what the design "
                  "model leaves out (docs/remus100-6dof.md)")


def method_list(sc: Scenario, estimators: Sequence[str] | None = None,
                trackings: Sequence[str] | None = None,
                architectures: Sequence[str] | None = None) -> list[tuple[str, str, str, str]]:
    """(name, estimator, tracking, architecture) of each method to run: names are the
    estimator when only estimators vary, the tracking law when only the law varies, the
    architecture when only it varies, else the varying ones joined by '-'.

    Parameters
    ----------
    sc : Scenario
        Gives the defaults (its estimator, tracking law and architecture).
    estimators, trackings, architectures : sequence of str, optional
        Estimator modes, tracking laws and information architectures to combine.

    Returns
    -------
    list of (str, str, str, str)
    """
    est = list(estimators or [sc.estimator])
    trk = list(trackings or [sc.tracking])
    arc = list(architectures or [sc.architecture])
    out = []
    for a in arc:
        for e in est:
            for t in trk:
                parts = [x for x, many in ((a, len(arc) > 1), (e, len(est) > 1),
                                           (t, len(trk) > 1)) if many]
                out.append(("-".join(parts) or e, e, t, a))
    return out


def fleet_layout(sc: Scenario) -> FleetLayout | None:
    """The recording layout of a fleet scenario.

    Parameters
    ----------
    sc : Scenario

    Returns
    -------
    FleetLayout or None
        None for a single stacked system or a fleet whose vehicles have no NED positions.
    """
    from plant_model.fleet import fleet_info

    from .recording import FleetLayout
    if sc.fleet is None:
        return None
    info = fleet_info(sc.fleet, sc.system)
    if info.position_index is None:
        return None
    N = info.N

    def block(per: int) -> np.ndarray:
        return np.arange(N * per).reshape(N, per)

    return FleetLayout(
        position_index=info.position_index, error_index=block(info.s),
        control_index=block(info.q), error_names=info.output_names,
        control_names=info.input_names, leader_output=info.leader_output,
        offsets=info.offsets, edges=info.edges, pinned=info.pinned,
        state_index=block(info.p), state_names=info.state_names,
        disturbance_index=block(info.r), disturbance_names=info.disturbance_names,
    )


def record_stride(sc: Scenario, record_hz: float | None = None) -> int:
    """Steps between recorded samples: every step for a single system; for a fleet about
    ``record_hz`` samples per second (default 20 Hz), which keeps .rrd files of large
    fleets to tens of megabytes (every step is still simulated and summarised).

    Parameters
    ----------
    sc : Scenario
    record_hz : float, optional
        Recorded samples per second, Hz.

    Returns
    -------
    int
        The stride, at least 1.
    """
    if record_hz is None:
        if sc.fleet is None:
            return 1
        record_hz = 20.0
    return max(1, int(round(1.0 / (record_hz * sc.h))))


def simulate(sc: Scenario, modes: Sequence[str] | None, seeds: Sequence[int], out_dir: Path | str,
             *, progress: bool = True, log: Callable[[str], None] = print,
             trackings: Sequence[str] | None = None,
             record_hz: float | None = None, workers: int | None = None,
             architectures: Sequence[str] | None = None) -> dict[str, Any]:
    """Co-simulate each method (estimator ``modes`` x tracking laws ``trackings``, each
    default the scenario's) on each seed; write ``<out>/<scenario>.rrd`` and summary.json.

    The .rrd holds the traces of the first seed of every method (same noise for all
    methods); the summary holds statistics over all seeds, the predictions (Lyapunov
    equation of the sampled closed loop plus, for a planned leader path, its mean motion)
    and the steady-state tracking error of each method. The .rrd is written by a child
    process (:mod:`orchestrator.recording.background`) that imports Rerun meanwhile.

    Parameters
    ----------
    sc : Scenario
    modes : sequence of str or None
        Estimator modes (None: the scenario's).
    seeds : sequence of int
        Noise seeds; every method sees the same noise for a seed.
    out_dir : Path or str
        Output folder (created).
    progress : bool
        Show a progress bar (after one second), only when standard error is a terminal
        (redirected output gets the per-run lines only, no carriage returns).
    log : callable
        Receives one line per run.
    trackings : sequence of str, optional
        Tracking laws (None: the scenario's).
    architectures : sequence of str, optional
        Information architectures of a per-vehicle fleet (None: the scenario's).
    record_hz : float, optional
        Recording rate of fleets, Hz (:func:`record_stride`).
    workers : int, optional
        Worker processes for the seeds after each method's first (default one per core;
        1: all in this process; :mod:`orchestrator.parallel`); results do not depend on it.

    Returns
    -------
    dict
        The summary also written to ``summary.json``.
    """
    from .recording.background import BackgroundWriter

    t0 = time.perf_counter()
    check_memory(sc, len(method_list(sc, modes, trackings, architectures)))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    # the .rrd writer imports Rerun in a child while we simulate; SIGINT / SIGTERM stop
    # the runs between steps and keep what was simulated
    from .parallel import seed_pool
    runs = len(method_list(sc, modes, trackings, architectures))
    # the per-vehicle runs stay in this process (their FMUs are many small instances)
    workers = 1 if sc.deployment == "per-vehicle" else workers
    with BackgroundWriter() as writer, stop_on_signals() as stop, \
            seed_pool(sc.steps, len(seeds), runs, workers) as pool:
        return _simulate(sc, modes, seeds, out, writer, t0, progress=progress, log=log,
                         trackings=trackings, record_hz=record_hz, stop=stop, pool=pool,
                         architectures=architectures)


def _simulate(sc: Scenario, modes: Sequence[str] | None, seeds: Sequence[int], out: Path,
              writer: Any, t0: float, *, progress: bool, log: Callable[[str], None],
              trackings: Sequence[str] | None, record_hz: float | None,
              stop: StopFlag, pool: Any = None,
              architectures: Sequence[str] | None = None) -> dict[str, Any]:
    from controller_fmu.regulator import tracking_law

    from .per_vehicle_run import PerVehicleRuns

    cfg = scenario_config(sc)
    methods_run = method_list(sc, modes, trackings, architectures)
    pv = PerVehicleRuns(sc, out / "fmus") if sc.deployment == "per-vehicle" else None
    if pv is None:
        fmus = build_fmus(cfg, out / "fmus")
    else:
        for arch in dict.fromkeys(a for *_, a in methods_run):
            pv.fmus(arch)
        fmus = pv.all_fmus()
    # the stacked design only where a stacked or centralized law needs it (a distributed
    # fleet of 100 vehicles designs per vehicle, in its controller FMUs)
    stacked = {t for _, _, t, a in methods_run if pv is None or a == "centralized"}
    model = discretize(sc.system, sc.h) if stacked else None
    laws = {t: tracking_law(sc.system, t) for t in stacked}
    design = next(iter(laws.values())).design if laws else None
    methods: dict[str, Any] = {}
    rrd_runs: dict[str, dict[str, np.ndarray]] = {}
    rrd_links: dict[str, list[str]] = {}
    loop_us: list[float] = []
    window: tuple[float, float] | None = None
    bar = None
    if progress and sys.stderr.isatty():
        from tqdm import tqdm
        bar = tqdm(total=len(methods_run) * len(seeds) * sc.steps, unit="step", delay=1.0,
                   leave=False, unit_scale=True)
        log = bar.write
    layout = fleet_layout(sc)
    formation = (None if layout is None else
                 (layout.position_index, layout.offsets, layout.edges, sc.h))
    skipped: list[ModelError] = []
    bounds: dict[int, float | None] = {}
    notes: set[str] = set()
    for name, mode, tracking, arch in methods_run:
        Ks = laws[tracking].Ks if tracking in laws else None
        try:
            if pv is not None:
                pred0, pred, pred_window, k0 = pv.predictions(arch, mode, tracking)
            else:
                est = make_estimator(sc.system, model, mode)
        except ModelError as exc:       # impossible for this scenario: run the others
            if len(methods_run) == 1:
                raise
            skipped.append(exc)
            methods[name] = {"skipped": str(exc), "estimator": mode, "tracking": tracking,
                             "architecture": arch, "seeds_completed": 0}
            log(f"{name:>9s}: skipped: {exc}")
            continue
        if pv is None:
            pred0, pred, pred_window, k0 = method_predictions(sc, model, est, Ks)
        window = (k0 * sc.h, sc.T)
        note = stationarity_note(sc.T, k0 * sc.h, pred0.settling_time)
        if note is not None:
            notes.add(note)
        per_seed, link_ages = [], []
        # the seeds after the first on local worker processes (orchestrator.parallel)
        pooled = {s: pool.submit(fmus, cfg, mode, s, sc.steps, tracking, k0, sc.system.Q,
                                 sc.system.R, formation)
                  for s in seeds[1:]} if pool and pv is None else {}
        for seed in seeds:
            if stop:
                break
            if seed in pooled:
                stats, loop_s = pooled[seed].result()
                if bar is not None:
                    bar.update(sc.steps)
                loop_us.append(loop_s / sc.steps * 1e6)
                per_seed.append(stats)
                log(f"{name:>9s} seed {seed}: cost rate {stats['cost_rate']:.4g} (worker "
                    f"process), {loop_s:.2f} s")
                continue
            res = (pv.run(arch, mode, tracking, seed, progress=bar, stop=stop) if pv else
                   run_cosimulation(fmus, cfg, mode=mode, seed=seed, steps=sc.steps,
                                    progress=bar, tracking=tracking, stop=stop))
            if name not in rrd_runs and res.steps:
                rrd_runs[name] = res.traces
                if "links" in res.info:
                    rrd_links[name] = res.info["links"]
            if res.info["interrupted_by"]:
                reached = res.steps * sc.h
                log(f"{name:>9s} seed {seed}: interrupted by {res.info['interrupted_by']} at "
                    f"t = {reached:.6g} s (not in the statistics)")
                break
            loop_us.append(res.loop_s / sc.steps * 1e6)
            per_seed.append(run_stats(res.traces, sc.system.Q, sc.system.R, k0, formation))
            if formation is not None:
                per_seed[-1]["segments"] = run_segments(sc.fleet["leader"], res.traces, k0)
            if "link_age" in res.traces:
                link_ages.append((res.info["links"], res.traces["link_age"]))
            log(f"{name:>9s} seed {seed}: cost rate {per_seed[-1]['cost_rate']:.4g} "
                f"(predicted {None if pred.cost_rate is None else round(pred.cost_rate, 4)}), "
                f"{res.loop_s:.2f} s")
        methods[name] = (method_summary(per_seed, pred) if per_seed else
                         {"note": "no seed completed before the interruption"})
        if per_seed and formation is not None:
            methods[name].update(formation_summary(
                [st["formation"] for st in per_seed], list(seeds[:len(per_seed)])))
            if all("segments" in st for st in per_seed):
                methods[name].update(segment_summary([st["segments"] for st in per_seed]))
        if link_ages:
            methods[name].update(pv.network_entries(arch, mode, tracking, link_ages, k0))
        if per_seed and pred_window is not None:
            methods[name]["cost_rate"]["predicted_window"] = pred_window.cost_rate
            methods[name]["rms_e"]["predicted_window"] = pred_window.rms_e
        if per_seed and sc.nonlinear_vehicles and pred.cost_rate is not None:
            methods[name]["prediction_note"] = "; ".join(filter(None, [
                methods[name].get("prediction_note"), NONLINEAR_NOTE]))
        methods[name]["estimator"] = mode
        methods[name]["tracking"] = tracking
        methods[name]["architecture"] = arch
        #: the sampled closed loop's stability margin: largest |eigenvalue| of its error part
        methods[name]["spectral_radius"] = pred0.spectral_radius
        if per_seed and sc.fleet is not None:
            if k0 not in bounds:                # one per window, not one per method
                bounds[k0] = fleet_bound(sc, k0)
            methods[name]["cost_rate_full_information"] = bounds[k0]
        methods[name]["seeds_completed"] = len(per_seed)
        if stop:
            break
    if bar is not None:
        bar.close()
    if len(skipped) == len(methods_run):
        raise ModelError(f"no method can run on this scenario: {skipped[0]}")
    rrd_path = out / f"{file_stem(sc.name)}.rrd"
    stride = record_stride(sc, record_hz)
    recorded = min((len(next(iter(tr.values()))) for tr in rrd_runs.values()), default=0)
    if recorded:          # an interrupted compare: every method up to the shortest run
        rrd_runs = {m: {k: v[:recorded] for k, v in tr.items()} for m, tr in rrd_runs.items()}
        rrd_info = writer.write(rrd_path, rrd_runs, sc.h,
                                recording_name=f"{sc.name} ({', '.join(rrd_runs)})",
                                fleet=layout, stride=stride, links=rrd_links or None)
    else:
        rrd_path.unlink(missing_ok=True)          # never leave an earlier run's .rrd
        rrd_info = {"bytes": 0, "signals": 0, "rrd_s": 0.0}
    summary = {
        "scenario": sc.name,
        "source": sc.source,
        "h": sc.h,
        "T": sc.T,
        "steps": sc.steps,
        "seeds": [int(s) for s in seeds],
        "noise_convention": sc.system.noise_convention,
        "consensus": None if sc.fleet is None else sc.fleet["graph"].get("consensus",
                                                                         "in-plant"),
        "deployment": sc.deployment,
        **fleet_comparison(sc, methods),
        "stats_window_s": list(window) if window else None,
        "stationary": not notes,
        "stationarity_note": "; ".join(sorted(notes)) or None,
        "methods": methods,
        "design": None if design is None else {
            "closed_loop_poles": [[float(z.real), float(z.imag)] for z in design.closed_loop_poles],
            "residuals": design.residuals,
            "Kx": design.Kx.tolist(), "Kz": design.Kz.tolist(), "Kw": design.Kw.tolist(),
        },
        "interrupted": bool(stop),
        "interrupted_by": stop.name,
        "time_reached_s": recorded * sc.h if stop else sc.T,
        "rrd": {"path": str(rrd_path) if recorded else None, "traces_of_seed": int(seeds[0]),
                "recorded_every_steps": stride, "recorded_steps": recorded, **rrd_info},
        "timing": {"cosim_loop_us_per_step_mean": float(np.mean(loop_us)) if loop_us else None},
        "fmus": {k: {"path": str(v), "bytes": v.stat().st_size} for k, v in fmus.items()},
        "wall_s": time.perf_counter() - t0,
        "versions": versions(),
    }
    if sc.fleet is not None and design is not None:
        summary["design"].pop("Kx")
        summary["design"].pop("Kz")
        summary["design"].pop("Kw")
    write_text_atomically(out / "summary.json", json.dumps(summary, indent=2))
    return summary
