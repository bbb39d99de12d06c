"""``auv-cosim``: build the FMUs, run, compare, plot, validate and benchmark.

Every error a user can cause (a bad scenario, an impossible design, an FMU that
refuses a call) is printed as one line naming the problem, with exit status 2.
"""
from __future__ import annotations

import argparse
import math
import os
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from controller_fmu.regulator import TRACKING_MODES
from controller_fmu.vehicle_law import ARCHITECTURES, DEPLOYMENTS
from estimator_fmu.estimators import ESTIMATOR_MODES
from plant_model.linalg_checks import ModelError
from plant_model.network import RECEIVERS

from .cli_args import _count, _positive, parse_floats, parse_seeds, positive_metres
from .cli_bench import _fleet_sizes, cmd_bench
from .cosim.instance import CosimError
from .cosim.system import AlgebraicLoopError
from .interop.common import ExportError
from .outputs import OutputFolderError, file_stem, output_folder
from .scenario import Scenario, ScenarioError, builtin_scenarios, load_scenario

ROOT = Path(__file__).resolve().parent.parent


class UsageError(RuntimeError):
    """Bad input found by a command itself (not by the scenario loader or an FMU)."""


def _scenario(args: argparse.Namespace) -> Scenario:
    sc = load_scenario(args.scenario)
    return sc.with_run(T=getattr(args, "T", None), h=getattr(args, "h", None),
                       seed=getattr(args, "seed", None), estimator=getattr(args, "estimator", None),
                       tracking=getattr(args, "tracking", None),
                       deployment=getattr(args, "deployment", None),
                       architecture=getattr(args, "architecture", None),
                       network={k: v for k in ("latency", "period", "loss", "receiver")
                                if (v := getattr(args, k, None)) is not None})


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
        sep = m.get("min_separation")
        if m.get("formation_error_rms"):
            worst = max(m["formation_error_rms"], key=m["formation_error_rms"].get)
            print(f"{'':>10s}   formation error RMS (window) worst edge {worst} "
                  f"{m['formation_error_rms'][worst]:#.3g} m"
                  + ("" if sep is None else
                     f"; closest approach {sep['m']:#.3g} m (vehicles {sep['vehicles'][0]} "
                     f"and {sep['vehicles'][1]} at t = {sep['time_s']:.4g} s, seed "
                     f"{sep['seed']})"))
    notes = {m.get("prediction_note") for m in summary["methods"].values()} - {None}
    for note in sorted(notes):
        print(f"note: {note}")
    if summary.get("cost_rate_full_information") is not None:
        line = (f"full-information bound (every state known, the same cost) "
                f"{summary['cost_rate_full_information']:#.4g}")
        if summary.get("price_of_decentralization") is not None:
            pred = summary.get("price_of_decentralization_predicted")
            line += (f"; price of decentralization J_distributed / J_centralized "
                     f"{summary['price_of_decentralization']:.4f}"
                     + ("" if pred is None else f" (predicted {pred:.4f})"))
        print(line)
    if summary.get("stationarity_note"):
        window = ", ".join(f"{n} {m['cost_rate']['predicted_window']:#.4g}"
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
            print(f"{k:>18s}: {p} ({p.stat().st_size} bytes)")
        if sc.deployment == "per-vehicle":
            print("(no cross-check references for the per-vehicle FMUs: they are written "
                  "for the stacked deployment's three FMUs)")
        elif not args.no_crosscheck:
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
    if what == "plants":
        return _compare_plants(sc, args)
    if what == "architectures" and sc.deployment != "per-vehicle":
        raise UsageError("--what architectures compares the centralized and distributed laws "
                         "of the per-vehicle deployment: add --deployment per-vehicle (or set "
                         "[simulation] deployment = \"per-vehicle\")")
    choices = {"estimators": ESTIMATOR_MODES, "tracking": TRACKING_MODES,
               "architectures": ARCHITECTURES}[what]
    picked = list(choices)
    if args.methods:
        picked = [m.strip() for m in args.methods.split(",") if m.strip()]
        unknown = [m for m in picked if m not in choices]
        if unknown or not picked or len(set(picked)) < len(picked):
            raise UsageError(
                f"--methods {args.methods!r}: "
                + (f"{', '.join(unknown)} is not one of the {what} ({', '.join(choices)})"
                   if unknown else "give each method once, separated by commas"))
    modes = picked if what == "estimators" else None
    trackings = picked if what == "tracking" else None
    architectures = picked if what == "architectures" else None
    check_memory(sc, len(method_list(sc, modes, trackings, architectures)))
    with output_folder(args.out or f"out/{file_stem(sc.name)}_compare", "compare") as out:
        summary = simulate(sc, modes, args.seeds, out, progress=not args.quiet,
                           log=(lambda s: None) if args.quiet else print, trackings=trackings,
                           workers=args.workers, architectures=architectures)
    return _print_summary(summary, out)


def _compare_plants(sc: Scenario, args: argparse.Namespace) -> int:
    """compare --what plants: the linear and the nonlinear REMUS 100, same FMUs otherwise."""
    from plant_model.vehicle_models import family_of

    from .plant_study import PLANTS, compare_plants, plant_table
    if sc.deployment != "per-vehicle":
        raise UsageError("--what plants runs the nonlinear vehicle, which is its own FMU: add "
                         "--deployment per-vehicle (or set [simulation] deployment = "
                         "\"per-vehicle\")")
    models = [v.get("model", "remus100") for v in sc.fleet["vehicles"]]
    other = next((i for i, m in enumerate(models, 1)
                  if family_of(m) != family_of(PLANTS[0])), None)
    if other is not None or args.methods:
        raise UsageError("--what plants compares remus100 with remus100-6dof (no --methods)"
                         + ("" if other is None else
                            f"; vehicle {other} is a {models[other - 1]!r} model"))
    with output_folder(args.out or f"out/{file_stem(sc.name)}_plants", "compare") as out:
        summary = compare_plants(sc, args.seeds, out, progress=not args.quiet,
                                 log=(lambda s: None) if args.quiet else print)
    print("\n".join(plant_table(summary)))
    print(f"wrote {out / 'summary.json'}")
    if summary.get("interrupted"):
        from .interrupt import EXIT_STATUS
        sig = summary.get("interrupted_by")
        print(f"auv-cosim: interrupted by {sig}: kept what each plant's run produced and "
              f"{out / 'summary.json'} (marked \"interrupted\": true)", file=sys.stderr)
        return EXIT_STATUS.get(sig, 130)
    return 0


def cmd_envelope(args: argparse.Namespace) -> int:
    """envelope: the grid of orchestrator.envelope, one line per point."""
    from .envelope import run_envelope
    sc = _scenario(args)
    if sc.fleet is None or sc.deployment != "per-vehicle":
        raise UsageError("envelope runs a per-vehicle fleet: give a fleet scenario and "
                         "--deployment per-vehicle")
    with output_folder(args.out or f"out/{file_stem(sc.name)}_envelope", "envelope") as out:
        summary = run_envelope(sc, args.speeds, args.radii, args.currents, args.tolerance,
                               out, log=print)
    held = sum(p["holds"] for p in summary["envelope"]["points"])
    print(f"{held} of {len(summary['envelope']['points'])} points hold within "
          f"{args.tolerance:g} m; wrote {out / 'summary.json'}")
    return 130 if summary["interrupted"] else 0


def cmd_export(args: argparse.Namespace) -> int:
    sc = _scenario(args)
    if args.format == "native":
        from .cosim.native import NativeBuildError, compiler
        try:
            compiler()                      # no C compiler: say so before any folder exists
        except NativeBuildError as exc:
            raise UsageError(str(exc)) from None
    with output_folder(args.out or f"out/{file_stem(sc.name)}_{args.format}", "export") as out:
        if args.format == "native":
            from .cosim.native import NativeBuildError
            from .interop.native import export_native
            try:
                paths = export_native(sc, out)
            except NativeBuildError as exc:
                raise UsageError(str(exc)) from None
            fmus = [p.name for p in paths.values() if p.suffix == ".fmu"]
            native = [f for f in fmus if f.endswith("Native.fmu")]
            kept = [f for f in fmus if f not in native]
            print(f"native FMUs for scenario {sc.name} in {out}: {', '.join(native)}"
                  + (f" (and, not linear, needing Python: {', '.join(kept)})" if kept else "")
                  + f"; OSP system {paths['system'].name}, SSP archive {paths['ssp'].name}")
        elif args.format == "osp":
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
            sp.add_argument("--deployment", choices=DEPLOYMENTS,
                            help="fleets: one set of FMUs for the stacked fleet, or a vehicle, "
                                 "estimator and controller FMU per AUV (default: scenario's, "
                                 "stacked unless it says otherwise)")
            sp.add_argument("--architecture", choices=ARCHITECTURES,
                            help="per-vehicle fleets: the paper's stacked law cut by vehicle "
                                 "(centralized) or neighbour-only information (distributed) "
                                 "(default: scenario's)")
            net = sp.add_argument_group(
                "acoustic links (per-vehicle fleets; override or start the scenario's "
                "[network])")
            net.add_argument("--latency", type=float, help="every link's latency, s")
            net.add_argument("--period", type=float, help="every link's message period, s")
            net.add_argument("--loss", type=float, help="every link's loss probability")
            net.add_argument("--receiver", choices=RECEIVERS,
                             help="what a receiver does between messages: propagate the "
                                  "newest with the sender's model (default) or hold it")
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
    sp.add_argument("--what", choices=("estimators", "tracking", "architectures", "plants"),
                    help="compare the estimator modes (default for a single system), the "
                         "tracking laws lq and regulator (default for a fleet), the "
                         "centralized and distributed architectures (per-vehicle fleets) or "
                         "the linear and the nonlinear 6-DOF REMUS 100 (per-vehicle fleets)")
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

    sp = sub.add_parser("envelope", help="where a per-vehicle formation holds: a grid of "
                                         "leader speed, turn radius and current strength")
    common(sp)
    sp.add_argument("--speeds", type=parse_floats, default=[1.0, 1.5, 2.0],
                    help="leader speeds, m/s (default: 1,1.5,2)")
    sp.add_argument("--radii", type=parse_floats, default=[math.inf, 50.0, 25.0],
                    help="leader turn radii, m; inf: a straight line (default: inf,50,25)")
    sp.add_argument("--currents", type=parse_floats, default=[0.1, 0.3],
                    help="ocean-current standard deviations, m/s (default: 0.1,0.3)")
    sp.add_argument("--tolerance", type=positive_metres, default=3.0,
                    help="the formation holds when the largest tracking error over the "
                         "window stays within this, m (default: 3)")
    sp.add_argument("--out", help="output folder (default: out/<scenario>_envelope)")
    sp.set_defaults(func=cmd_envelope)

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
                                       "system (libcosim) or an SSP archive (fmpy, SSP tools); "
                                       "native: compiled FMUs of the design, no Python needed, "
                                       "with both system files")
    sp.add_argument("format", choices=("osp", "ssp", "native"))
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
    sp.add_argument("--native", action="store_true",
                    help="us/step of the loop with native FMUs: in our master (with the "
                         "pythonfmu plant, all native), in the C host, in ecos, and a fused "
                         "numpy loop (--T sets the simulated time, default 200 s)")
    sp.add_argument("--remus", action="store_true",
                    help="the nonlinear REMUS 100: derivative and step in numpy and compiled, "
                         "vehicle FMU doStep against the linear one, compile time")
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
