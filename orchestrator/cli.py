"""``auv-cosim``: build the FMUs, run, compare, plot, validate and benchmark.

Every error a user can cause (a bad scenario, an impossible design, an FMU that
refuses a call) is printed as one line naming the problem, with exit status 2.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

from controller_fmu.regulator import TRACKING_MODES
from estimator_fmu.estimators import ESTIMATOR_MODES
from plant_model.linalg_checks import ModelError

from .cosim.instance import CosimError
from .cosim.system import AlgebraicLoopError
from .interop.common import ExportError
from .outputs import OutputFolderError, file_stem, output_folder
from .scenario import Scenario, ScenarioError, builtin_scenarios, load_scenario

ROOT = Path(__file__).resolve().parent.parent


class UsageError(RuntimeError):
    """Bad input found by a command itself (not by the scenario loader or an FMU)."""


def parse_seeds(text: str) -> list[int]:
    """'0-9' -> 0..9, '1,4,7' -> [1, 4, 7], '3' -> [3]."""
    seeds: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if "-" in part:
                a, b = (int(x) for x in part.split("-", 1))
                if b < a:
                    raise ValueError
                seeds.extend(range(a, b + 1))
            else:
                seeds.append(int(part))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"seeds {text!r}: expected a range '0-9', a list '1,4,7' or one seed") from None
    if any(s < 0 or s > 2**31 - 1 for s in seeds):
        raise argparse.ArgumentTypeError(
            f"seeds {text!r}: seeds must be from 0 to 2^31 - 1 (a 32-bit FMI Integer)")
    if len(seeds) > 100_000:
        raise argparse.ArgumentTypeError(f"seeds {text!r}: {len(seeds)} seeds is too many "
                                         "for one compare (at most 100000)")
    repeated = sorted(s for s, c in Counter(seeds).items() if c > 1)
    if repeated:
        raise argparse.ArgumentTypeError(
            f"seeds {text!r}: seed(s) {', '.join(map(str, repeated))} given more than once "
            "(each would count twice in the statistics)")
    return seeds


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number of seconds")
    return v


def _count(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be at least 1")
    return v


def _scenario(args: argparse.Namespace) -> Scenario:
    sc = load_scenario(args.scenario)
    return sc.with_run(T=getattr(args, "T", None), h=getattr(args, "h", None),
                       seed=getattr(args, "seed", None), estimator=getattr(args, "estimator", None),
                       tracking=getattr(args, "tracking", None))


def viewer_command() -> str:
    """How to start the Rerun viewer from this shell: ``rerun`` if that is the one on PATH
    next to this Python, else the path of the one installed with this package (relative
    to the working folder when under it, e.g. ``.venv/bin/rerun``)."""
    import shutil
    ours = Path(sys.executable).parent / "rerun"
    found = shutil.which("rerun")
    if found and (not ours.exists() or Path(found).resolve() == ours.resolve()):
        return "rerun"
    if not ours.exists():
        return "rerun"
    try:
        return shlex.quote(str(ours.relative_to(Path.cwd())))
    except ValueError:
        return shlex.quote(str(ours))


def _print_summary(summary: dict, out: Path) -> int:
    """Print the summary table and where the files are; the exit status: 0, or 130 / 143
    for a run stopped by SIGINT / SIGTERM (after one line saying what was kept)."""
    print(f"scenario {summary['scenario']}: T = {summary['T']} s, h = {summary['h']} s, "
          f"{summary['steps']} steps, seeds {summary['seeds']}, "
          f"noise convention '{summary['noise_convention']}', statistics over "
          f"t in [{summary['stats_window_s'][0]:.3g}, {summary['stats_window_s'][1]:.3g}) s")
    print(f"{'method':>10s} {'cost rate':>12s} {'(std)':>9s} {'predicted':>10s}   "
          "rms e (sim / pred)")
    for name, m in summary["methods"].items():
        if "skipped" in m:
            print(f"{name:>10s}   skipped: {m['skipped']}")
            continue
        if "cost_rate" not in m:
            print(f"{name:>10s}   {m.get('note', 'no statistics')}")
            continue
        c = m["cost_rate"]
        pred = "n/a" if c["predicted"] is None else f"{c['predicted']:#.4g}"
        sim_e, pred_e = m["rms_e"]["mean"], m["rms_e"]["predicted"]
        if len(sim_e) <= 4:
            rms = ", ".join(
                f"{a:#.3g}/{'n/a' if b is None else format(b, '#.3g')}"
                for a, b in zip(sim_e, pred_e or [None] * len(sim_e)))
        else:       # a fleet: the worst component, and the noise-free (steady) error
            steady = m.get("steady_error", {}).get("max_rms_e_without_noise_predicted")
            rms = (f"max {max(sim_e):#.3g}/"
                   f"{'n/a' if not pred_e else format(max(pred_e), '#.3g')}"
                   + ("" if steady is None else f"; steady error (noise-free RMS) {steady:#.3g}"))
        print(f"{name:>10s} {c['mean']:#12.4g} {c['std']:#9.3g} {pred:>10s}   {rms}")
    if summary.get("stationarity_note"):
        window = ", ".join(f"{n} {m['cost_rate']['predicted_window']:.4g}"
                           for n, m in summary["methods"].items()
                           if m.get("cost_rate", {}).get("predicted_window") is not None)
        print(f"note: {summary['stationarity_note']}"
              + (f"; expected cost rate over this window: {window}" if window else ""))
    rrd = summary["rrd"]["path"]
    if rrd:
        print(f"wrote {rrd} and {out / 'summary.json'}; wall time {summary['wall_s']:.1f} s")
        print(f"open it with: {viewer_command()} {shlex.quote(rrd)}")
    if summary.get("interrupted"):
        from .interrupt import EXIT_STATUS
        sig = summary["interrupted_by"]
        kept = (f"{rrd} (traces to t = {summary['time_reached_s']:.6g} s)" if rrd
                else "no traces (stopped before the first steps)")
        print(f"auv-cosim: interrupted by {sig} at t = {summary['time_reached_s']:.6g} s of "
              f"{summary['T']} s: kept {kept} and {out / 'summary.json'} (marked "
              f"\"interrupted\": true; statistics over the seeds that completed)",
              file=sys.stderr)
        return EXIT_STATUS.get(sig, 130)
    return 0


def cmd_build(args: argparse.Namespace) -> int:
    from .workflow import build, write_fmu_readme
    sc = _scenario(args)
    with output_folder(args.out, "build") as out:
        paths = build(sc, out)
        if out.resolve() == (ROOT / "fmus").resolve():
            write_fmu_readme(sc, out / "README.md")
        for k, p in paths.items():
            print(f"{k:>10s}: {p} ({p.stat().st_size} bytes)")
        if not args.no_crosscheck:
            from .interop.crosscheck import write_crosscheck
            from .workflow import scenario_config
            written = write_crosscheck(paths, scenario_config(sc), out / "crosscheck")
            print(f"cross-check references (<Model>_in.csv, _ref.csv, _ref.opt) for "
                  f"{', '.join(written)} in {out / 'crosscheck'}")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from .workflow import check_memory, simulate
    sc = _scenario(args)
    check_memory(sc, 1)                     # before anything is created
    with output_folder(args.out or f"out/{file_stem(sc.name)}_{sc.estimator}_seed{sc.seed}",
                       "run") as out:
        summary = simulate(sc, [sc.estimator], [sc.seed], out, progress=not args.quiet,
                           log=(lambda s: None) if args.quiet else print)
    return _print_summary(summary, out)


def cmd_compare(args: argparse.Namespace) -> int:
    from .workflow import check_memory, method_list, simulate
    sc = _scenario(args)
    what = args.what or ("tracking" if sc.fleet is not None else "estimators")
    choices = ESTIMATOR_MODES if what == "estimators" else TRACKING_MODES
    picked = list(choices)
    if args.methods:
        picked = [m.strip() for m in args.methods.split(",") if m.strip()]
        unknown = [m for m in picked if m not in choices]
        if unknown or not picked or len(set(picked)) < len(picked):
            raise UsageError(
                f"--methods {args.methods!r}: "
                + (f"{', '.join(unknown)} is not one of the {what} ({', '.join(choices)})"
                   if unknown else "give each method once, separated by commas"))
    modes, trackings = (picked, None) if what == "estimators" else (None, picked)
    check_memory(sc, len(method_list(sc, modes, trackings)))
    with output_folder(args.out or f"out/{file_stem(sc.name)}_compare", "compare") as out:
        summary = simulate(sc, modes, args.seeds, out, progress=not args.quiet,
                           log=(lambda s: None) if args.quiet else print, trackings=trackings,
                           workers=args.workers)
    return _print_summary(summary, out)


def cmd_export(args: argparse.Namespace) -> int:
    sc = _scenario(args)
    with output_folder(args.out or f"out/{file_stem(sc.name)}_{args.format}", "export") as out:
        if args.format == "osp":
            from .interop.osp import export_osp
            paths = export_osp(sc, out)
            print(f"OSP system for scenario {sc.name} in {out}: {paths['system'].name}, "
                  + ", ".join(p.name for k, p in paths.items() if k != "system"))
            print(f"run it with libcosim: cosim run {paths['system']}  (or libcosimpy)")
        else:
            from .interop.ssp import export_ssp
            path = export_ssp(sc, out / f"{file_stem(sc.name)}.ssp")
            print(f"SSP archive for scenario {sc.name}: {path} (fmpy: simulate_ssp('{path}'))")
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    import tempfile

    from fmpy.validation import validate_fmu

    from .workflow import build
    if args.fmus:
        import zipfile
        paths = {p.stem: p for p in (Path(x) for x in args.fmus)}
        missing = [str(p) for p in paths.values() if not p.is_file()]
        if missing:
            raise UsageError(f"FMU file(s) not found: {', '.join(missing)}")
        not_zip = [str(p) for p in paths.values() if not zipfile.is_zipfile(p)]
        if not_zip:
            raise UsageError(f"not an FMU (an FMU is a zip archive): {', '.join(not_zip)}")
        tmp = None
    else:
        tmp = tempfile.TemporaryDirectory(prefix="auv_validate_")
        paths = build(_scenario(args), Path(tmp.name))
    bad = 0
    for name, p in paths.items():
        problems = validate_fmu(str(p))
        bad += len(problems)
        verdict = "no problem" if not problems else f"{len(problems)} problem(s)"
        print(f"{name:>10s}: {p.name}: {verdict}")
        for prob in problems:
            print(f"            - {prob}")
    if tmp:
        tmp.cleanup()
    return 1 if bad else 0


def cmd_campaign(args: argparse.Namespace) -> int:
    from .campaign.runner import run_campaign
    return run_campaign(args.spec, args.out, scheduler=args.scheduler, workers=args.workers,
                        engine=args.engine)


def cmd_plot(args: argparse.Namespace) -> int:
    from .plotting import RunFolderError, parse_formats, plot_run
    try:
        formats = parse_formats(args.format)
        written = plot_run(args.run_dir, args.out, formats)
    except (RunFolderError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    for path in written:
        print(path)
    print(f"wrote {len(written)} files into {written[0].parent if written else args.out}")
    return 0


def _fleet_sizes(text: str) -> list[int]:
    try:
        sizes = [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--fleet {text!r}: expected sizes like '1,5,20,50'") from None
    if not sizes or any(n < 1 for n in sizes):
        raise argparse.ArgumentTypeError(f"--fleet {text!r}: sizes must be positive")
    return sizes


def cmd_bench_fleet(args: argparse.Namespace) -> int:
    from .bench import benchmark_fleet
    rows = []
    print(f"{'N':>3s} {'states':>6s} {'design s':>9s} {'filter s':>9s} {'build s':>8s} "
          f"{'mD kB (p/e/c)':>18s} {'init s (p/e/c)':>18s} {'cosim us':>9s} {'mono us':>8s} "
          f"{'ratio':>6s} {'FMI us':>7s} {'max diff':>9s}")
    for N in args.fleet:
        r = benchmark_fleet(N, T=args.T or 300.0, mode=args.estimator or "kalman",
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


def _printed_as_json(args: argparse.Namespace, r: dict, rounds: str = "") -> bool:
    """Print a benchmark's figures as JSON (--json) and say so, or print its heading line."""
    if args.json:
        print(json.dumps(r, indent=2))
        return True
    print(f"scenario {r['scenario']}, estimator {r['mode']}, {r['steps']} steps of {r['h']} s"
          f"{rounds}; load average {r['loadavg'][0]:.2f} on {r['cpus']} CPUs")
    return False


def cmd_bench_tools(args: argparse.Namespace) -> int:
    from .bench import benchmark_tools
    sc = _scenario(args)
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


def cmd_bench_startup(args: argparse.Namespace) -> int:
    from .bench import benchmark_startup
    sc = _scenario(args)
    r = benchmark_startup(sc)
    if _printed_as_json(args, r, f", median of {r['repeats']} rounds"):
        return 0
    print(f"  auv-cosim run (subprocess, warm FMU cache)  {r['run_warm_s']:6.2f} s   "
          f"{r['ratio_run_to_reference_loop']:.2f}x the reference loop (target <= 2.0)")
    print(f"  auv-cosim run (subprocess, empty cache)     {r['run_cold_s']:6.2f} s")
    print(f"  reference loop (in process, numpy)          {r['reference_loop_s']:6.2f} s")
    print(f"  python -c 'import orchestrator.cli'         {r['import_cli_s']:6.2f} s; "
          f"python -c pass {r['python_s']:.2f} s")
    return 0


def cmd_bench_campaign(args: argparse.Namespace) -> int:
    from .campaign.bench import benchmark_campaign
    r = benchmark_campaign()
    if args.json:
        print(json.dumps(r, indent=2))
        return 0
    print(f"paper scenario (T = 300 s, h = 0.01 s); load average {r['loadavg'][0]:.2f} on "
          f"{r['cpus']} CPUs (after: {r['loadavg_after'][0]:.2f})")
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


def cmd_bench(args: argparse.Namespace) -> int:
    from .bench import benchmark
    if args.campaign:
        return cmd_bench_campaign(args)
    if args.fleet:
        return cmd_bench_fleet(args)
    if args.tools:
        return cmd_bench_tools(args)
    if args.startup:
        return cmd_bench_startup(args)
    sc = _scenario(args)
    r = benchmark(sc, mode=sc.estimator, seed=sc.seed)
    if _printed_as_json(args, r):
        return 0
    print(f"  co-simulation loop (3 FMUs)   {r['cosim_loop_s']:8.3f} s  "
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


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="auv-cosim",
        description="Optimal consensus tracking control of AUVs (Yuan, Zhang, Zhou) as three "
                    "FMI 2.0 co-simulation FMUs coupled on fmpy, traced to Rerun.")
    sub = p.add_subparsers(dest="command", required=True)

    def common(sp: argparse.ArgumentParser, *, run: bool = True) -> None:
        sp.add_argument("--scenario", default="paper",
                        help=f"built-in name ({', '.join(builtin_scenarios())}) or a .toml file "
                             "(default: paper)")
        if run:
            sp.add_argument("--T", type=_positive, help="simulated time, s (default: scenario's)")
            sp.add_argument("--h", type=_positive,
                            help="communication step, s (default: scenario's)")

    sp = sub.add_parser("build", help="build the three FMUs (default into fmus/)")
    common(sp)
    sp.add_argument("--out", default=str(ROOT / "fmus"), help="output folder (default: fmus/)")
    sp.add_argument("--tracking", choices=TRACKING_MODES,
                    help="the controller FMU's default tracking law (default: scenario's)")
    sp.add_argument("--no-crosscheck", action="store_true",
                    help="skip the FMI cross-check reference files (500 steps of the closed loop)")
    sp.set_defaults(func=cmd_build)

    sp = sub.add_parser("run", help="co-simulate one estimator mode, write .rrd and summary.json")
    common(sp)
    sp.add_argument("--estimator", choices=ESTIMATOR_MODES, help="estimator mode (default: kalman)")
    sp.add_argument("--seed", type=int, help="noise seed (default: scenario's)")
    sp.add_argument("--out", help="output folder (default: out/<scenario>_<estimator>_seed<seed>)")
    sp.add_argument("--quiet", action="store_true", help="no progress bar or per-run lines")
    sp.set_defaults(func=cmd_run)

    sp.add_argument("--tracking", choices=TRACKING_MODES,
                    help="tracking law: lq (the paper) or regulator (default: scenario's)")

    sp = sub.add_parser("compare", help="the three estimator modes (or, for a fleet, the two "
                                        "tracking laws) on the same noise and seeds")
    common(sp)
    sp.add_argument("--what", choices=("estimators", "tracking"),
                    help="compare the estimator modes (default for a single system) or the "
                         "tracking laws lq and regulator (default for a fleet)")
    sp.add_argument("--methods",
                    help="which of them, comma-separated, e.g. 'kalman,ideal' or 'lq' "
                         "(default: all; a mode impossible for the scenario is skipped and "
                         "the summary says why)")
    sp.add_argument("--seeds", type=parse_seeds, default=list(range(10)),
                    help="seeds: '0-9' (default), '1,4,7' or one seed")
    sp.add_argument("--out", help="output folder (default: out/<scenario>_compare)")
    sp.add_argument("--quiet", action="store_true", help="no progress bar or per-run lines")
    sp.add_argument("--workers", type=_count,
                    help="worker processes for the seeds after each method's first (default: "
                         "one per core; 1: all in this process); the results do not depend "
                         "on it")
    sp.set_defaults(func=cmd_compare)

    sp = sub.add_parser("campaign", help="Monte Carlo runs and parameter sweeps from a spec "
                                         "file, on local worker processes or a Dask cluster")
    sp.add_argument("spec", help="campaign spec (.toml): base scenario, seeds, [sweep] axes")
    sp.add_argument("--scheduler", help="address of a running Dask scheduler "
                                        "(tcp://host:port); default: a local cluster")
    sp.add_argument("--workers", type=_count, help="worker processes of the local cluster "
                                                   "(default: one per core)")
    sp.add_argument("--out", help="output folder (default: out/campaign_<name>)")
    sp.add_argument("--engine", choices=("fmu", "numpy"),
                    help="fmu: the three FMUs; numpy: the closed loop vectorised over seeds "
                         "where it applies (default: the spec's, else fmu)")
    sp.set_defaults(func=cmd_campaign)

    sp = sub.add_parser("export", help="the FMUs and a system file for other tools: an OSP "
                                       "system (libcosim) or an SSP archive (fmpy, SSP tools)")
    sp.add_argument("format", choices=("osp", "ssp"))
    common(sp)
    sp.add_argument("--tracking", choices=TRACKING_MODES, help="the controller's tracking law")
    sp.add_argument("--estimator", choices=ESTIMATOR_MODES, help="the estimator's mode")
    sp.add_argument("--seed", type=int, help="noise seed written as the plant's initial value")
    sp.add_argument("--out", help="output folder (default: out/<scenario>_<format>)")
    sp.set_defaults(func=cmd_export)

    sp = sub.add_parser("plot", help="static figures of a run folder (PNG, SVG, PDF): the "
                                     "paper's figures 2-7, or a fleet's paths and errors")
    sp.add_argument("run_dir", metavar="RUN_DIR",
                    help="a folder written by 'auv-cosim run' or 'compare'")
    sp.add_argument("--out", help="output folder (default: RUN_DIR/figures)")
    sp.add_argument("--format", default="png,svg",
                    help="comma-separated formats from png, svg, pdf (default: png,svg)")
    sp.set_defaults(func=cmd_plot)

    sp = sub.add_parser("validate", help="fmpy validate the FMUs (built afresh, or given)")
    common(sp, run=False)
    sp.add_argument("fmus", nargs="*", help=".fmu files to validate instead of building")
    sp.set_defaults(func=cmd_validate)

    sp = sub.add_parser("bench", help="time the co-simulation against the monolithic loop")
    common(sp)
    sp.add_argument("--estimator", choices=ESTIMATOR_MODES, help="estimator mode (default: kalman)")
    sp.add_argument("--seed", type=int, help="noise seed")
    sp.add_argument("--tracking", choices=TRACKING_MODES, help="tracking law")
    sp.add_argument("--fleet", type=_fleet_sizes,
                    help="benchmark generated grid fleets of these sizes instead, e.g. 1,5,20,50 "
                         "(REMUS 100 vehicles, circle leader; --T sets the simulated time, "
                         "default 300 s)")
    sp.add_argument("--tools", action="store_true",
                    help="the same FMUs in our orchestrator, libcosim (libcosimpy) and fmpy's "
                         "simulate_ssp (--T sets the simulated time, default 50 s)")
    sp.add_argument("--startup", action="store_true",
                    help="'auv-cosim run' as a subprocess (start to exit, cold and warm FMU "
                         "cache) against the in-process monolithic loop")
    sp.add_argument("--campaign", action="store_true",
                    help="campaign throughput: runs per hour of the paper scenario on 1 and 2 "
                         "local workers (FMU engine) and the numpy engine, overhead per task, "
                         "design-cache gain at N = 50")
    sp.add_argument("--json", action="store_true", help="print the figures as JSON")
    sp.set_defaults(func=cmd_bench)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "seed", None) is not None and not 0 <= args.seed <= 2**31 - 1:
        parser.error(f"--seed {args.seed}: seeds must be from 0 to 2^31 - 1 "
                     "(a 32-bit FMI Integer)")
    try:
        return args.func(args)
    except (ScenarioError, ModelError, CosimError, ExportError, AlgebraicLoopError,
            OutputFolderError, UsageError) as exc:
        print(f"auv-cosim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:          # an output folder that is a file, unwritable, full, ...
        where = f" {exc.filename}" if exc.filename else ""
        print(f"auv-cosim {args.command}: error: cannot write or read{where}: "
              f"{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:        # a bug of ours, not bad input: say so, keep the traceback
        log = _write_bug_report(args)
        print(f"auv-cosim {args.command}: internal error (a bug in auv-cosim, not in your "
              f"input): {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
              f"; traceback in {log}; please report it with that file", file=sys.stderr)
        return 2


def _write_bug_report(args: argparse.Namespace) -> str:
    """Write the current exception's traceback, the command line and the versions to a log
    file (``$AUV_COSIM_CACHE/../logs`` or ``~/.cache/auv-cosim/logs``; else the temporary
    folder); its path, or a note that none could be written."""
    import platform
    import tempfile
    import time
    import traceback
    text = (f"auv-cosim {' '.join(sys.argv[1:])}\n{time.strftime('%Y-%m-%d %H:%M:%S')}  "
            f"python {platform.python_version()} on {platform.platform()}\n\n"
            + traceback.format_exc())
    cache = os.environ.get("AUV_COSIM_CACHE")
    base = Path(cache).parent if cache else Path.home() / ".cache" / "auv-cosim"
    for folder in (base / "logs", Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f"auv-cosim-{args.command}-{time.strftime('%Y%m%d-%H%M%S')}-" \
                            f"{os.getpid()}.log"
            path.write_text(text, encoding="utf-8")
            return str(path)
        except OSError:
            continue
    return "(no log: no writable folder)"


def console() -> None:
    """The ``auv-cosim`` command: :func:`main`, then leave without tearing the interpreter
    down. Every file is closed and every temporary folder removed by then; what remains is
    freeing numpy, scipy and the FMU libraries module by module (about 0.2 s), and
    pythonfmu 0.7's library-unload hook, which touches freed memory (see the README, "A
    non-Python host")."""
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    console()
