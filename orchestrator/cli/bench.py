"""``auv-cosim bench``: the benchmark commands' printing (the figures come from
:mod:`orchestrator.benchmarks`)."""
from __future__ import annotations

import argparse
import json
from collections.abc import Callable

from estimator_fmu.registry import DEFAULT_ESTIMATOR

from .args import _fleet_sizes
from .common import add_fmu_options, add_method_options, add_scenario_options, scenario_of
from .errors import UsageError

__all__ = ["add_bench", "cmd_bench"]


def cmd_bench_per_vehicle(args: argparse.Namespace) -> int:
    from ..benchmarks.per_vehicle import benchmark_per_vehicle
    arch = args.architecture or "distributed"
    rows = []
    print(f"per-vehicle deployment, {arch} architecture (generated survey grids)")
    print(f"{'N':>4s} {'FMUs':>5s} {'design s':>9s} {'build s':>8s} {'max mD kB':>10s} "
          f"{'init s':>7s} {'cosim us':>9s} {'us/veh':>7s} {'mono us':>8s} {'ratio':>6s} "
          f"{'max diff':>9s} {'pred s':>7s}")
    for N in args.fleet:
        r = benchmark_per_vehicle(N, architecture=arch, T=args.T or 20.0,
                                  mode=args.estimator or DEFAULT_ESTIMATOR,
                                  tracking=args.tracking or "regulator", seed=args.seed or 0)
        rows.append(r)
        md = max(r["model_description_bytes"].values()) / 1e3

        def opt(key: str, fmt: str, r: dict = r) -> str:
            return format(r[key], fmt) if key in r else "-"
        print(f"{N:4d} {r['fmu_instances']:5d} {r['design_s']:9.3f} {r['build_s']:8.2f} "
              f"{md:10.1f} {r['setup_s']:7.2f} {r['cosim_us_per_step']:9.0f} "
              f"{r['cosim_us_per_step'] / N:7.0f} {opt('monolithic_us_per_step', '8.1f')} "
              f"{opt('ratio', '6.0f')} {opt('max_abs_difference_u', '9.1e')} "
              f"{opt('prediction_s', '7.1f')}", flush=True)
    r = rows[-1]
    print(f"({r['steps']} steps of {r['h']} s each; load average {r['loadavg'][0]:.2f} on "
          f"{r['cpus']} CPUs; 'init s': extract, instantiate and initialize every FMU; "
          f"'pred s': the stacked Lyapunov prediction, timed apart)")
    if args.json:
        print(json.dumps(rows, indent=2))
    return 0


def cmd_bench_fleet(args: argparse.Namespace) -> int:
    from ..benchmarks.paper import benchmark_fleet
    rows = []
    print(f"{'N':>3s} {'states':>6s} {'design s':>9s} {'filter s':>9s} {'build s':>8s} "
          f"{'mD kB (p/e/c)':>18s} {'init s (p/e/c)':>18s} {'cosim us':>9s} {'mono us':>8s} "
          f"{'ratio':>6s} {'FMI us':>7s} {'max diff':>9s}")
    for N in args.fleet:
        r = benchmark_fleet(N, T=args.T or 300.0, mode=args.estimator or DEFAULT_ESTIMATOR,
                            tracking=args.tracking or "regulator", seed=args.seed or 0)
        rows.append(r)
        keys = ("plant", "estimator", "controller")
        md = "/".join(f"{r['model_description_bytes'][k] / 1e3:.0f}" for k in keys)
        it = "/".join(f"{r['instantiate_initialize_s'][k]:.2f}" for k in keys)
        print(f"{N:3d} {r['state_size']:6d} {r['design_s']:9.3f} {r['filter_gain_s']:9.3f} "
              f"{r['build_s']:8.2f} {md:>18s} {it:>18s} {r['cosim_us_per_step']:9.1f} "
              f"{r['monolithic_us_per_step']:8.1f} {r['ratio_loop']:6.2f} "
              f"{r['fmi_overhead_us_per_step']:7.1f} {r['max_abs_difference']:9.1e}", flush=True)
    r = rows[-1]
    print(f"({r['steps']} steps of {r['h']} s each; load average {r['loadavg'][0]:.2f} "
          f"on {r['cpus']} CPUs; "
          f"'FMI us' = co-simulation minus monolithic loop per step)")
    if args.json:
        print(json.dumps(rows, indent=2))
    return 0


def _json_printed(args: argparse.Namespace, r: dict) -> bool:
    """Print a benchmark's figures as JSON when --json asks for it; whether it did."""
    if args.json:
        print(json.dumps(r, indent=2))
    return bool(args.json)


def _load(r: dict) -> str:
    """``load average 0.71 on 2 CPUs (after: 0.80)``: the load before and after a benchmark."""
    return (f"load average {r['loadavg'][0]:.2f} on {r['cpus']} CPUs "
            f"(after: {r['loadavg_after'][0]:.2f})")


def _printed_as_json(args: argparse.Namespace, r: dict, rounds: str = "") -> bool:
    """Print a benchmark's figures as JSON (--json) and say so, or print its heading line."""
    if _json_printed(args, r):
        return True
    print(f"scenario {r['scenario']}, estimator {r['mode']}, {r['steps']} steps of {r['h']} s"
          f"{rounds}; load average {r['loadavg'][0]:.2f} on {r['cpus']} CPUs")
    return False


def cmd_bench_tools(args: argparse.Namespace) -> int:
    from ..benchmarks.paper import benchmark_tools
    sc = scenario_of(args)
    steps = int(round((args.T or 50.0) / sc.h))
    r = benchmark_tools(sc, steps)
    if _printed_as_json(args, r, f", median of {r['repeats']} rounds"):
        return 0
    print(f"  ours, Gauss-Seidel        {r['ours_gauss_seidel_us_per_step']:8.1f} us/step")
    print(f"  ours, Jacobi              {r['ours_jacobi_us_per_step']:8.1f} us/step")
    print(f"  libcosim (libcosimpy)     {r['libcosim_us_per_step']:8.1f} us/step   "
          f"ours {r['speedup_gauss_seidel_vs_libcosim']:.1f}x faster (target 5x)")
    print(f"  fmpy simulate_ssp         {r['simulate_ssp_us_per_step']:8.1f} us/step   "
          f"ours {r['speedup_gauss_seidel_vs_simulate_ssp']:.1f}x faster")
    print(f"  ({', '.join(f'{k} {v}' for k, v in r['versions'].items())})")
    return 0


def cmd_bench_native(args: argparse.Namespace) -> int:
    from ..benchmarks.native import benchmark_native, benchmark_native_fleet
    sc = scenario_of(args)
    r = benchmark_native(sc, int(round((args.T or 200.0) / sc.h)))
    r["fleet"] = benchmark_native_fleet()
    if _printed_as_json(args, r):
        return 0
    rows = (("python", "pythonfmu FMUs, our master"),
            ("native_ctrl_est", "native controller + estimator, pythonfmu plant, our master"),
            ("native_master", "all native, our Python master (fmpy, ctypes)"),
            ("native_compiled", "all native, our compiled master (C loop; target <= 3)"),
            ("native_c_host", "all native, C host (orchestrator/interop/native_host)"),
            ("native_ecos", "all native, ecos (C++), no CSV"),
            ("fused_numpy", "fused numpy loop, one gemv per step"))
    for key, label in rows:
        v = r[key]
        print(f"  {label:62s} " + ("      -  (not available)" if v is None
                                   else f"{v:8.2f} us/step"))
    f = r["fleet"]
    print(f"  {f['scenario']} per-vehicle distributed, all native ({f['components']} FMUs, "
          f"{f['calls_per_step']} FMI calls/step), {f['steps']} steps; load average "
          f"{f['loadavg'][0]:.2f}; set-up {f['setup_s']:.1f} s; traces equal: "
          f"{f['traces_equal']}")
    for master, label in (("native", "compiled master (target <= 1 ms/step)"),
                          ("python", "Python master")):
        print(f"  {label:62s} {f[f'{master}_ms_per_step']:8.3f} ms/step, {f['run_T']:g} s run: "
              f"loop {f[f'{master}_projected_loop_s']:.0f} s (projected)")
    return 0


def cmd_bench_remus(args: argparse.Namespace) -> int:
    from ..benchmarks.remus import benchmark_remus
    r = benchmark_remus()
    if _json_printed(args, r):
        return 0
    print(f"  nonlinear REMUS 100; {_load(r)}; numba {'on' if r['jit'] else 'off'}")
    print(f"  derivative          numpy {r['derivative_numpy_us']:8.1f} us   compiled "
          f"{r['derivative_kernel_us']:6.2f} us")
    print(f"  communication step  numpy {r['step_numpy_us']:8.1f} us   compiled "
          f"{r['step_kernel_us']:6.2f} us   (autopilots, one RK4 step of 0.01 s)")
    print(f"  vehicle FMU doStep  AuvRemus6dof {r['fmu_step_us_remus100-6dof']:6.1f} us   "
          f"AuvVehicle (linear) {r['fmu_step_us_remus100']:6.1f} us   per vehicle and step")
    print(f"  compiling the kernel: {r['compile_cold_s']:.1f} s in a fresh process, "
          f"{r['compile_cached_s']:.1f} s from numba's disk cache")
    return 0


def cmd_bench_startup(args: argparse.Namespace) -> int:
    from ..benchmarks.paper import benchmark_startup
    sc = scenario_of(args)
    r = benchmark_startup(sc)
    if _printed_as_json(args, r, f", median of {r['repeats']} rounds"):
        return 0
    print(f"  auv-cosim run (subprocess, warm FMU cache)  {r['run_warm_s']:6.2f} s   "
          f"{r['ratio_run_to_reference_loop']:.2f}x the reference loop")
    if r["run_native_s"] is not None:
        print(f"  auv-cosim run --fmus native (warm cache)    {r['run_native_s']:6.2f} s   "
              f"{r['ratio_native_run_to_reference_loop']:.2f}x the reference loop")
    else:
        print("  auv-cosim run --fmus native: not measured (no C compiler)")
    print(f"  auv-cosim run (subprocess, empty cache)     {r['run_cold_s']:6.2f} s")
    print(f"  reference loop (in process, numpy)          {r['reference_loop_s']:6.2f} s")
    print(f"  python -c 'import orchestrator.cli'         {r['import_cli_s']:6.2f} s; "
          f"python -c pass {r['python_s']:.2f} s")
    return 0


def cmd_bench_campaign(args: argparse.Namespace) -> int:
    from ..benchmarks.campaign import benchmark_campaign
    r = benchmark_campaign()
    if _json_printed(args, r):
        return 0
    print(f"paper scenario (T = 300 s, h = 0.01 s); {_load(r)}")
    for key, label in (("fmu_1_workers", "FMU engine, 1 worker "), ("fmu_2_workers",
                       "FMU engine, 2 workers"), ("numpy_1_worker", "numpy engine, 1 worker")):
        x = r[key]
        print(f"  {label:24s} {x['runs_per_hour']:9.0f} runs/h (whole command, "
              f"{x['runs']} runs in {x['command_s']:.1f} s), {x['runs_per_hour_tasks']:9.0f} "
              f"runs/h on the cluster ({x['tasks_s']:.1f} s)")
    print(f"  numpy engine loop: {r['numpy_1_worker']['us_per_step_per_seed']:.2f} us per "
          "step and seed")
    o = r["overhead"]
    print(f"  overhead per task: {1e3 * o['per_task_s']:.0f} ms ({o['tasks']} one-step tasks "
          f"on 2 workers in {o['tasks_s']:.2f} s, {o['inside_runs_s']:.2f} s inside the runs)")
    d = r["design_cache"]
    print(f"  design cache at N = {d['N']} ({d['states']} states, T = {d['T']} s): "
          f"{d['per_seed_off_s']:.2f} s per seed without, {d['per_seed_on_s']:.2f} s with "
          f"(saves {d['saved_per_seed_s']:.2f} s per seed; the point's design and prediction "
          f"{d['design_on_s']:.2f} s once per task)")
    return 0


def cmd_bench_predictions(args: argparse.Namespace) -> int:
    from ..benchmarks.predictions import benchmark_predictions
    sc = scenario_of(args)
    if sc.network is None or sc.deployment != "per-vehicle":
        raise UsageError("bench --predictions times the predictions over acoustic links: give "
                         "a per-vehicle fleet with links, e.g. --scenario formation-4 "
                         "--deployment per-vehicle --latency 1 --period 2 --loss 0.2")
    archs = [args.architecture] if args.architecture else ["centralized", "distributed"]
    r = benchmark_predictions(sc, archs, mode=args.estimator or DEFAULT_ESTIMATOR,
                              tracking=args.tracking or "regulator")
    if _json_printed(args, r):
        return 0
    print(f"{sc.name} over links (T = {sc.T} s, h = {sc.h} s); {_load(r)}")
    print(f"{'architecture':>12s} {'states':>6s} {'error':>6s} {'links':>5s} {'cycle':>6s} "
          f"{'L ms':>6s} {'stationary s':>12s} {'critical s':>10s} {'cached s':>8s}   "
          "radius, window cost, critical loss")
    for x in r["rows"]:
        crit = "none" if x["critical_loss"] is None else f"{x['critical_loss']:.4g}"
        print(f"{x['architecture']:>12s} {x['states']:6d} {x['error_states']:6d} "
              f"{x['links']:5d} {x['cycle_steps']:6d} {x['cycle_map_ms']:6.2f} "
              f"{x['stationary_s']:12.2f} {x['critical_loss_s']:10.2f} {x['cached_s']:8.3f}   "
              f"{x['second_moment_radius']:.10g}, {x['cost_rate_window']:.10g}, {crit}")
    print("('L ms': one application of the second-moment cycle map; 'stationary s': the "
          "radius and the window's expected cost, as a run computes them; 'critical s': the "
          "critical-loss search (--predict full); 'cached s': both again for a second run, "
          "from the prediction cache)")
    return 0


def cmd_bench_phases(args: argparse.Namespace) -> int:
    """``bench --phases``: a whole ``auv-cosim run`` of the scenario options, split."""
    from ..benchmarks.phases import benchmark_phases
    r = benchmark_phases(vars(args))
    if _json_printed(args, r):
        return 0
    print(f"auv-cosim run {' '.join(r['argv'])}: {r['command_s']:.1f} s ({r['steps']} steps); "
          f"{_load(r)}")
    labels = {"build": "build (FMUs, native FMUs)", "design": "design (gains, filters)",
              "predictions": "predictions (and the bound)",
              "instantiate": "instantiate, initialize, free FMUs", "loop": "loop",
              "statistics": "statistics (traces, formation)", "recording": "recording (.rrd)",
              "other": "other (inside the command)"}
    for key, label in labels.items():
        v = r["phases_s"][key]
        print(f"  {label:38s} {v:8.2f} s  {100 * v / r['command_s']:5.1f} %")
    print(f"  {'start-up and exit (imports, parsing)':38s} {r['startup_and_exit_s']:8.2f} s  "
          f"{100 * r['startup_and_exit_s'] / r['command_s']:5.1f} %")
    ratio = r["outside_to_loop"]
    print(f"  outside the loop {r['outside_loop_s']:.1f} s, inside {r['loop_s']:.1f} s: "
          + ("-" if ratio is None else f"{ratio:.2f}x") + " (target <= 1)")
    return 0


#: bench's modes (one at most: a mutually exclusive group, in this order in --help) ->
#: (the command that times it, its option's help); none: the paper loop against the
#: monolithic one
MODES: dict[str, tuple[Callable[[argparse.Namespace], int], str]] = {
    "fleet": (cmd_bench_fleet,
              "benchmark generated grid fleets of these sizes instead, e.g. 1,5,20,50 "
              "(REMUS 100 vehicles, circle leader; --T sets the simulated time, "
              "default 300 s)"),
    "tools": (cmd_bench_tools,
              "the same FMUs in our orchestrator, libcosim (libcosimpy) and fmpy's "
              "simulate_ssp (--T sets the simulated time, default 50 s)"),
    "startup": (cmd_bench_startup,
                "'auv-cosim run' as a subprocess (start to exit, cold and warm FMU "
                "cache) against the in-process monolithic loop"),
    "campaign": (cmd_bench_campaign,
                 "campaign throughput: runs per hour of the paper scenario on 1 and 2 "
                 "local workers (FMU engine) and the numpy engine, overhead per task, "
                 "design-cache gain at N = 50"),
    "native": (cmd_bench_native,
               "us/step of the loop with native FMUs: in our Python master (with "
               "the pythonfmu plant, all native), in our compiled master, in the C "
               "host, in ecos, and a fused numpy loop (--T sets the simulated time, "
               "default 200 s); ms/step of formation-100 per-vehicle native in both "
               "masters"),
    "remus": (cmd_bench_remus,
              "the nonlinear REMUS 100: derivative and step in numpy and compiled, "
              "vehicle FMU doStep against the linear one, compile time"),
    "predictions": (cmd_bench_predictions,
                    "the predictions over acoustic links (per-vehicle fleet with "
                    "--latency/--period/--loss): the second moment and the critical-loss "
                    "search, cold and from the cache, per architecture"),
    "phases": (cmd_bench_phases,
               "a whole 'auv-cosim run' of the scenario options (a subprocess): "
               "its time split into build, design, predictions, instantiate, loop, "
               "statistics, recording, other and start-up, and outside the loop "
               "against inside it"),
}


def cmd_bench(args: argparse.Namespace) -> int:
    from ..benchmarks.paper import benchmark
    mode = next((m for m in MODES if getattr(args, m, None)), None)
    if mode in ("phases", "predictions"):       # these take a per-vehicle scenario as is
        return MODES[mode][0](args)
    if getattr(args, "deployment", None) == "per-vehicle":
        if not args.fleet:
            raise UsageError("bench --deployment per-vehicle times fleets of several sizes: "
                             "give them with --fleet, e.g. --fleet 4,20,50,100")
        return cmd_bench_per_vehicle(args)
    if mode is not None:
        return MODES[mode][0](args)
    sc = scenario_of(args)
    r = benchmark(sc, mode=sc.estimator, seed=sc.seed)
    if _printed_as_json(args, r):
        return 0
    print(f"{'  co-simulation loop (' + r['fmu_kind'] + ')':<32s}{r['cosim_loop_s']:8.3f} s  "
          f"{r['cosim_us_per_step']:7.2f} us/step")
    print(f"  .rrd writing                  {r['rrd_write_s']:8.3f} s  "
          f"({100 * r['rrd_fraction_of_run']:.1f} % of loop + rrd)")
    print(f"  monolithic numpy loop         {r['monolithic_s']:8.3f} s  "
          f"{r['monolithic_us_per_step']:7.2f} us/step")
    print(f"  ratio (loop + rrd) / monolithic  {r['ratio_cosim_to_monolithic']:.2f}   "
          f"(loop only {r['ratio_loop_only']:.2f}; target <= 1.5)")
    print(f"  loop / monolithic loop (setup excluded on both sides)  "
          f"{r['ratio_loop_to_reference_loop']:.2f}   (target <= 1.3)")
    print(f"  setup (extract, instantiate, initialize) {r['cosim_setup_s']:.3f} s; "
          f"build {r['build_s']:.3f} s")
    print("  FMI calls: " + ", ".join(f"{k} {v:.2f}" for k, v in r["fmi_calls"].items()))
    print(f"  max |co-simulation - monolithic| over all traces: {r['max_abs_difference']:.2e}")
    return 0


def add_bench(sub: argparse._SubParsersAction) -> None:
    """The ``bench`` command's sub-parser."""
    sp = sub.add_parser("bench", help="time the co-simulation against the monolithic loop")
    add_scenario_options(sp)
    add_method_options(sp)
    modes = sp.add_mutually_exclusive_group()       # one of MODES at most
    for name, (_, text) in MODES.items():
        # --fleet takes the sizes; every other mode is a flag
        kind = {"type": _fleet_sizes} if name == "fleet" else {"action": "store_true"}
        modes.add_argument(f"--{name}", help=text, **kind)
    sp.add_argument("--json", action="store_true", help="print the figures as JSON")
    add_fmu_options(sp)
    sp.set_defaults(func=cmd_bench)
