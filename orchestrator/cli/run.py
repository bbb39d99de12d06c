"""``auv-cosim run``, ``compare`` and ``envelope``: co-simulate a scenario, once, over
methods and seeds, or over a grid of operating points."""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from controller_fmu.regulator import TRACKING_MODES
from controller_fmu.vehicle_law import ARCHITECTURES
from estimator_fmu.registry import COMPARED_BY_DEFAULT, ESTIMATOR_MODES

from ..outputs import staged_output
from ..scenario import Scenario
from .args import _count, current_speeds, leader_speeds, parse_floats, parse_seeds, positive_metres
from .common import (
    add_fmu_options,
    add_force_option,
    add_master_option,
    add_method_options,
    add_predict_option,
    add_scenario_options,
    print_summary,
    scenario_of,
)
from .errors import UsageError

__all__ = ["add_compare", "add_envelope", "add_run", "cmd_compare", "cmd_envelope", "cmd_run"]


def _log(args: argparse.Namespace, st: Any) -> Callable[[str], None]:
    """The progress lines of a command (none with --quiet), the staging folder's path
    shown as the destination's."""
    if args.quiet:
        return lambda s: None
    return lambda s: print(st.relocate(s))


def cmd_run(args: argparse.Namespace) -> int:
    from ..running import simulate
    from ..running.checkpoint import CHECKPOINT_DIR, DEFAULT_EVERY_S
    from ..running.naming import default_out, run_identity
    from ..running.systems import check_run
    from ..swap import RUN, remove_tree
    resume = _resumed(args)
    sc = resume.scenario if resume is not None else scenario_of(args)
    if resume is not None and not args.quiet:
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(resume.saved_at))
        print(f"resuming at t = {resume.master.step * sc.h:g} s of {sc.T:g} s "
              f"(checkpoint of {when})")
    options = resume.options if resume is not None else {"predict": args.predict,
                                                         "master": args.master or "auto",
                                                         "record_hz": args.record_hz,
                                                         "record": args.record}
    check_run(sc, predict=options["predict"],   # every check, before anything is created
              record_hz=options.get("record_hz"), record=options.get("record"))
    live = _live(args)
    every = DEFAULT_EVERY_S if args.checkpoint_every is None else args.checkpoint_every
    out = args.resume or args.out or default_out(sc, sc.estimator, f"seed{sc.seed}")
    with staged_output(out, "run", identity=run_identity(sc, "run"),
                       force=True if resume is not None else args.force,
                       kind=RUN if every else "",
                       resume=(CHECKPOINT_DIR,) if resume is not None else ()) as st:
        summary = simulate(sc, [sc.estimator], [sc.seed], st.path, progress=not args.quiet,
                           log=_log(args, st), predict=options["predict"],
                           master=options["master"], checkpoint_every=every, resume=resume,
                           realtime=args.realtime, record_hz=options.get("record_hz"),
                           record=options.get("record"), live=live)
        complete = not summary.get("interrupted")
        if complete:                    # a finished run needs no checkpoint
            remove_tree(st.path / CHECKPOINT_DIR)
        out = st.finish(complete=complete)
    return print_summary(st.relocate(summary), out, st.note)


def _live(args: argparse.Namespace) -> str | None:
    """The URL of the viewer ``--live`` streams to (spawned if no URL was given), None
    without it; one that cannot be reached is refused in one line, before the run."""
    if args.live is None:
        return None
    from ..recording.live import LiveViewerError, live_url
    try:
        return live_url(args.live)
    except LiveViewerError as exc:
        raise UsageError(str(exc)) from None


def _resumed(args: argparse.Namespace) -> Any:
    """The checkpoint ``--resume OUT`` goes on from (None without it), read before the
    output folder is taken (a killed run's staging folder holds it); the options that
    would change the run are refused beside it, in one line."""
    if not args.resume:
        return None
    from ..running.checkpoint import find_checkpoint, read_checkpoint
    changed = [f"--{k.replace('_', '-')}" for k in ("estimator", "seed", "tracking", "fmus",
                                                    "master", "deployment", "architecture",
                                                    "latency", "period", "loss", "receiver",
                                                    "T", "h", "out", "record_hz",
                                                    "record")
               if getattr(args, k, None) is not None]
    if args.scenario != "paper":
        changed.insert(0, "--scenario")
    if changed:
        raise UsageError(f"--resume goes on with the run as it was checkpointed: drop "
                         f"{', '.join(changed)}")
    return read_checkpoint(find_checkpoint(Path(args.resume)))


def cmd_compare(args: argparse.Namespace) -> int:
    from ..running import method_list, simulate
    from ..running.naming import default_out, run_identity
    from ..running.systems import check_run
    sc = scenario_of(args)
    what = args.what or ("tracking" if sc.fleet is not None else "estimators")
    if what == "plants":
        return _compare_plants(sc, args)
    if what == "architectures" and sc.deployment != "per-vehicle":
        raise UsageError("--what architectures compares the centralized and distributed laws "
                         "of the per-vehicle deployment: add --deployment per-vehicle (or set "
                         "[simulation] deployment = \"per-vehicle\")")
    choices = {"estimators": ESTIMATOR_MODES, "tracking": TRACKING_MODES,
               "architectures": ARCHITECTURES}[what]
    picked = list(COMPARED_BY_DEFAULT if what == "estimators" else choices)
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
    check_run(sc, method_list(sc, modes, trackings, architectures), predict=args.predict,
              record_hz=args.record_hz, record=args.record)
    live = _live(args)
    tail = "compare" if args.what is None else f"compare-{what}"
    with staged_output(args.out or default_out(sc, tail), "compare",
                       identity=run_identity(sc, f"compare --what {what}"),
                       force=args.force) as st:
        summary = simulate(sc, modes, args.seeds, st.path, progress=not args.quiet,
                           log=_log(args, st), trackings=trackings,
                           workers=args.workers, architectures=architectures,
                           predict=args.predict, master=args.master or "auto",
                           record_hz=args.record_hz, record=args.record, live=live)
        out = st.finish(complete=not summary.get("interrupted"))
    return print_summary(st.relocate(summary), out, st.note)


def _compare_plants(sc: Scenario, args: argparse.Namespace) -> int:
    """compare --what plants: the linear and the nonlinear REMUS 100, same FMUs otherwise."""
    from plant_model.vehicle_models import family_of

    from ..running.naming import default_out, run_identity
    from ..running.plants import PLANTS, compare_plants, plant_table
    if sc.deployment != "per-vehicle":
        raise UsageError("--what plants runs the nonlinear vehicle, which is its own FMU: add "
                         "--deployment per-vehicle (or set [simulation] deployment = "
                         "\"per-vehicle\")")
    models = list(sc.fleet.model_names)
    other = next((i for i, m in enumerate(models, 1)
                  if family_of(m) != family_of(PLANTS[0])), None)
    if other is not None or args.methods:
        raise UsageError("--what plants compares remus100 with remus100-6dof (no --methods)"
                         + ("" if other is None else
                            f"; vehicle {other} is a {models[other - 1]!r} model"))
    from ..running.systems import check_native
    check_native(sc)
    with staged_output(args.out or default_out(sc, "plants"), "compare",
                       identity=run_identity(sc, "compare --what plants"),
                       force=args.force) as st:
        summary = compare_plants(sc, args.seeds, st.path, progress=not args.quiet,
                                 log=_log(args, st))
        out = st.finish(complete=not summary.get("interrupted"))
    summary = st.relocate(summary)
    print("\n".join(plant_table(summary)))
    print(f"wrote {out / 'summary.json'}")
    if summary.get("interrupted"):
        from ..interrupt import EXIT_STATUS
        sig = summary.get("interrupted_by")
        print(f"auv-cosim: interrupted by {sig}: kept what each plant's run produced and "
              f"{out / 'summary.json'} (marked \"interrupted\": true)"
              + (f"; {st.note}" if st.note else ""), file=sys.stderr)
        return EXIT_STATUS.get(sig, 130)
    return 0


def cmd_envelope(args: argparse.Namespace) -> int:
    """envelope: the grid of orchestrator.running.envelope, one line per point; exit
    status 0 when every point ran, 3 when some could not (counted in one line on stderr:
    orchestrator.exit_status)."""
    from ..running.envelope import run_envelope
    from ..running.naming import default_out, run_identity
    sc = scenario_of(args)
    if sc.fleet is None or sc.deployment != "per-vehicle":
        raise UsageError("envelope runs a per-vehicle fleet: give a fleet scenario and "
                         "--deployment per-vehicle")
    if args.write_spec:                       # the grid as a campaign spec, not run here
        from ..atomic import write_text_atomically
        from ..running.envelope import envelope_spec
        write_text_atomically(args.write_spec, envelope_spec(sc, args.speeds, args.radii,
                                                             args.currents))
        print(f"wrote {args.write_spec}: {len(args.speeds) * len(args.radii) * len(args.currents)}"
              f" points; run them with: auv-cosim campaign {args.write_spec} (each row's "
              f"max_error against the tolerance, {args.tolerance:g} m, says where it holds)")
        return 0
    from ..running.systems import check_native
    check_native(sc)                          # the grid's FMUs: refused before any folder
    with staged_output(args.out or default_out(sc, "envelope"), "envelope",
                       identity=run_identity(sc, "envelope"), force=args.force) as st:
        summary = run_envelope(sc, args.speeds, args.radii, args.currents, args.tolerance,
                               st.path, log=_log(args, st))
        out = st.finish(complete=not summary["interrupted"])
    summary = st.relocate(summary)
    if summary["interrupted"]:
        print(f"auv-cosim envelope: interrupted: kept the points that ran in "
              f"{out / 'summary.json'} (marked \"interrupted\": true)"
              + (f"; {st.note}" if st.note else ""), file=sys.stderr)
    held = sum(p["holds"] for p in summary["envelope"]["points"])
    failed = summary["envelope"]["failed"]
    print(f"{held} of {len(summary['envelope']['points'])} points hold within "
          f"{args.tolerance:g} m"
          + (f"; {failed} could not run (each one's reason in summary.json)" if failed else "")
          + f"; wrote {out / 'summary.json'}")
    from ..exit_status import OK, POINTS_FAILED, points_failed_line
    if failed:
        first = next(p for p in summary["envelope"]["points"] if p["failed"] is not None)
        print(points_failed_line("envelope", failed, len(summary["envelope"]["points"]),
                                 f"each reason in {out / 'summary.json'}", first["failed"]),
              file=sys.stderr)
    if summary["interrupted"]:
        return 130
    return POINTS_FAILED if failed else OK


#: envelope's default scenario: a per-vehicle fleet (the command runs nothing else)
ENVELOPE_SCENARIO = "survey-4-remus"


def add_run(sub: argparse._SubParsersAction) -> None:
    """The ``run`` command's sub-parser."""
    sp = sub.add_parser("run", help="co-simulate one estimator mode, write .rrd and summary.json")
    add_scenario_options(sp)
    add_method_options(sp)
    _add_run_outputs(sp, "out/<scenario>[_<system>]_<estimator>_seed<seed>; <system> names a "
                         "per-vehicle deployment and architecture, links, nonlinear vehicles, "
                         "native FMUs")
    add_fmu_options(sp)
    add_master_option(sp)
    long = sp.add_argument_group("long runs (docs/long-runs.md)")
    long.add_argument("--checkpoint-every", type=_seconds, metavar="S",
                      help="write a checkpoint every S wall-clock seconds (default 60: a "
                           "run shorter than a minute writes none; 0: none)")
    long.add_argument("--realtime", type=_factor, metavar="FACTOR",
                      help="pace the run to the wall clock: FACTOR simulated seconds per "
                           "second (1: real time); the overruns (steps that ended late) "
                           "and the worst lateness are reported")
    long.add_argument("--resume", metavar="OUT",
                      help="go on with the run in OUT from its last checkpoint (after a "
                           "kill or an interruption); the traces and summary equal an "
                           "uninterrupted run's")
    sp.set_defaults(func=cmd_run)


def _seconds(text: str) -> float:
    """A number of seconds >= 0 (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not value >= 0 or math.isinf(value):
        raise argparse.ArgumentTypeError(f"{text!r}: give seconds >= 0 (0: no checkpoints)")
    return value


def _positive_number(what: str) -> Callable[[str], float]:
    """An argparse type: a finite number > 0, refused naming ``what`` it is."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not value > 0 or math.isinf(value):
            raise argparse.ArgumentTypeError(f"{text!r}: give {what}")
        return value
    return parse


#: --realtime's and --record-hz's values
_factor = _positive_number("simulated seconds per wall-clock second, a number > 0 "
                           "(1: real time)")
_rate = _positive_number("samples per second of simulated time, a number > 0")


def _groups(text: str) -> tuple[str, ...]:
    """--record's groups: names separated by commas (each checked against the scenario's
    layout by :func:`orchestrator.running.systems.check_record`)."""
    names = tuple(n.strip() for n in text.split(","))
    if not all(names):
        raise argparse.ArgumentTypeError(f"{text!r}: name the groups separated by commas, "
                                         "e.g. error,control,scene")
    return names


def _add_run_outputs(sp: argparse.ArgumentParser, default_out: str) -> None:
    """--out, --force, --predict, --record-hz, --record and --live of run and compare."""
    sp.add_argument("--out", help=f"output folder (default: {default_out})")
    add_force_option(sp)
    add_predict_option(sp)
    sp.add_argument("--record-hz", type=_rate, metavar="HZ",
                    help="samples per second of simulated time in the .rrd (default: every "
                         "step for a single system, 20 for a fleet); every step is still "
                         "simulated and in the statistics")
    sp.add_argument("--record", type=_groups, metavar="GROUPS",
                    help="the outputs written to the .rrd, groups separated by commas "
                         "(default: all). A fleet: error, control, state, current, leader, "
                         "scene, actuators, setpoint, links; a single system: error, state, "
                         "control, disturbance, reference, measurement. The statistics and "
                         "summary.json use every output (docs/long-runs.md)")
    sp.add_argument("--live", nargs="?", const="spawn", metavar="URL",
                    help="watch the run in a Rerun viewer as it goes: one spawned (no URL) "
                         "or the one at URL (rerun+http://HOST:PORT/proxy); the .rrd is "
                         "written as without it (docs/long-runs.md)")


def add_compare(sub: argparse._SubParsersAction) -> None:
    """The ``compare`` command's sub-parser."""
    sp = sub.add_parser("compare", help="the three estimator modes (or, for a fleet, the two "
                                        "tracking laws) on the same noise and seeds")
    add_scenario_options(sp)
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
    _add_run_outputs(sp, "out/<scenario>[_<system>]_compare[-<what>]")
    sp.add_argument("--workers", type=_count,
                    help="worker processes for the seeds after each method's first (default: "
                         "one per core; 1: all in this process); the results do not depend "
                         "on it")
    add_fmu_options(sp)
    add_master_option(sp)
    sp.set_defaults(func=cmd_compare)


def add_envelope(sub: argparse._SubParsersAction) -> None:
    """The ``envelope`` command's sub-parser."""
    sp = sub.add_parser("envelope", help="where a per-vehicle formation holds: a grid of "
                                         "leader speed, turn radius and current strength")
    add_scenario_options(sp, default=ENVELOPE_SCENARIO)
    sp.add_argument("--speeds", type=leader_speeds, default=[1.0, 1.5, 2.0],
                    help="leader speeds, m/s (default: 1,1.5,2)")
    sp.add_argument("--radii", type=parse_floats, default=[math.inf, 50.0, 25.0],
                    help="leader turn radii, m; inf: a straight line (default: inf,50,25)")
    sp.add_argument("--currents", type=current_speeds, default=[0.1, 0.3],
                    help="ocean-current standard deviations, m/s (default: 0.1,0.3)")
    sp.add_argument("--tolerance", type=positive_metres, default=3.0,
                    help="the formation holds when the largest tracking error over the "
                         "window stays within this, m (default: 3)")
    sp.add_argument("--out", help="output folder (default: out/<scenario>[_<system>]_envelope)")
    sp.add_argument("--write-spec", metavar="SPEC.toml",
                    help="write the grid as a campaign spec instead of running it (auv-cosim "
                         "campaign runs it on local workers or a Dask cluster)")
    add_force_option(sp)
    sp.set_defaults(func=cmd_envelope)
