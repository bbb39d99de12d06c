"""What the ``auv-cosim`` commands share: the scenario options and the scenario they give,
the options of the commands that run FMUs, and the printed summary of a run or compare."""
from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from controller_fmu.vehicle_law import ARCHITECTURES, DEPLOYMENTS
from plant_model.acoustic.settings import RECEIVERS

from ..numbers import sig
from ..scenario import Scenario, builtin_scenarios, load_scenario
from .args import _positive
from .errors import UsageError

__all__ = ["ROOT", "add_fmu_options", "add_force_option", "add_master_option",
           "add_predict_option", "add_quiet_option",
           "add_scenario_options", "method_table", "print_summary", "stationarity_line",
           "summary_notes", "scenario_of", "viewer_command"]

ROOT = Path(__file__).resolve().parents[2]


def add_scenario_options(sp: argparse.ArgumentParser, *, run: bool = True,
                         default: str = "paper") -> None:
    """--scenario (``default`` when not given: a scenario the command accepts); with
    ``run``, also what changes the simulated system and run: the deployment and
    architecture, the acoustic links, --T and --h."""
    sp.add_argument("--scenario", default=default,
                    help=f"built-in name ({', '.join(builtin_scenarios())}) or a .toml file "
                         f"(default: {default})")
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


def add_fmu_options(sp: argparse.ArgumentParser) -> None:
    """The options of every command that runs the FMUs: run, compare, campaign and bench.
    A flag added here is a flag of all four."""
    from fmu_common.native_form import FMU_IMPLEMENTATIONS
    sp.add_argument("--fmus", choices=FMU_IMPLEMENTATIONS,
                    help="python: the pythonfmu FMUs; native: compiled (C) FMUs of every "
                         "component with a linear form or a C model (the REMUS 100 6-DOF "
                         "vehicles, the acoustic network, the guidance interface, the "
                         "multi-rate estimator), pythonfmu only for the linear vehicle with "
                         "[sensors]; needs a C compiler (default: the scenario's [simulation] "
                         "fmus, else python)")


def add_method_options(sp: argparse.ArgumentParser) -> None:
    """--estimator, --seed and --tracking: the one method and seed a command runs."""
    from controller_fmu.regulator import TRACKING_MODES
    from estimator_fmu.registry import DEFAULT_ESTIMATOR, ESTIMATOR_MODES
    sp.add_argument("--estimator", choices=ESTIMATOR_MODES,
                    help=f"estimator mode (default: the scenario's, else {DEFAULT_ESTIMATOR})")
    sp.add_argument("--seed", type=int, help="noise seed (default: the scenario's)")
    sp.add_argument("--tracking", choices=TRACKING_MODES,
                    help="tracking law: lq (the paper) or regulator (default: the scenario's)")


def add_master_option(sp: argparse.ArgumentParser) -> None:
    """--master: which master runs the systems (run and compare)."""
    sp.add_argument("--master", choices=("native", "python"),
                    help="native: the step loop compiled in C (orchestrator/cosim/"
                         "native_master.c); python: the Python loop, the reference; the "
                         "traces are the same bit for bit (default: native when every FMU "
                         "is native and a C compiler is present, else python)")


def add_predict_option(sp: argparse.ArgumentParser) -> None:
    """--predict: what the summary predicts besides the simulation."""
    sp.add_argument("--predict", choices=("none", "stationary", "full"), default="stationary",
                    help="none: no prediction (the summary's predicted figures null, with a "
                         "note); stationary: each method's stationary and window predictions "
                         "(about a second for formation-4 over links); full: also the "
                         "acoustic links' critical loss (a search over losses, seconds for "
                         "formation-4, cached) (default: stationary)")


def add_quiet_option(sp: argparse.ArgumentParser) -> None:
    """--quiet: no per-seed, per-point or progress lines; only the result and errors."""
    sp.add_argument("--quiet", action="store_true",
                    help="no per-seed, per-point or progress lines: only the result and "
                         "errors")


def add_force_option(sp: argparse.ArgumentParser) -> None:
    """--force: replace the outputs of another kind of run in the output folder."""
    sp.add_argument("--force", action="store_true",
                    help="replace what another kind of run (another deployment, "
                         "architecture, links, vehicle model or FMU kind) wrote into --out")


def scenario_of(args: argparse.Namespace) -> Scenario:
    """The scenario of the command line: --scenario, with the options given over its
    values."""
    sc = load_scenario(args.scenario)
    sc = sc.with_run(T=getattr(args, "T", None), h=getattr(args, "h", None),
                       seed=getattr(args, "seed", None), estimator=getattr(args, "estimator", None),
                       tracking=getattr(args, "tracking", None),
                       deployment=getattr(args, "deployment", None),
                       architecture=getattr(args, "architecture", None),
                       fmus=getattr(args, "fmus", None),
                       network={k: v for k in ("latency", "period", "loss", "receiver")
                                if (v := getattr(args, k, None)) is not None})
    if getattr(args, "architecture", None) is not None and sc.deployment != "per-vehicle":
        raise UsageError(f"--architecture {args.architecture}: the architecture is that of "
                         f"the per-vehicle deployment; {sc.name} runs {sc.deployment!r} (one "
                         "stacked controller): add --deployment per-vehicle")
    return sc


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


#: the share of the statistics window above which a design is said to live saturated
SATURATION_NOTE = 0.10
#: up to this many saturated vehicles are named one by one; more are counted
SATURATION_LISTED = 6


def saturation_line(method: str, per_vehicle: list[float] | None) -> str | None:
    """One line naming the vehicles saturated more than SATURATION_NOTE of the window
    (None when none is)."""
    over = [(i, f) for i, f in enumerate(per_vehicle or [], start=1) if f > SATURATION_NOTE]
    if not over:
        return None
    if len(over) <= SATURATION_LISTED:
        which = ", ".join(f"vehicle {i} {f:.0%}" for i, f in over)
    else:                               # a fleet: how many, the range, the worst one
        worst = max(over, key=lambda x: x[1])
        which = (f"{len(over)} of {len(per_vehicle or [])} vehicles, "
                 f"{min(f for _, f in over):.0%} to {worst[1]:.0%} "
                 f"(the most: vehicle {worst[0]})")
    return (f"note: {method}: saturated more than {SATURATION_NOTE:.0%} of the statistics "
            f"window: {which} (the design asks more force than the vehicle gives: [design] "
            "force_budget or bandwidth)")


def _rms_cell(m: dict) -> str:
    """The rms e cell of a method: simulated, with the prediction after a slash where one
    exists; a fleet's worst component (and the noise-free steady error when predicted)."""
    sim_e = m["rms_e"]["mean"]
    pred_e = m["rms_e"].get("predicted") or [None] * len(sim_e)
    if len(sim_e) <= 4:
        return ", ".join(sig(a, 3) + ("" if b is None else f"/{sig(b, 3)}")
                         for a, b in zip(sim_e, pred_e))
    preds = [b for b in pred_e if b is not None]
    steady = (m.get("steady_error") or {}).get("max_rms_e_without_noise_predicted")
    return (f"max {sig(max(sim_e), 3)}" + (f"/{sig(max(preds), 3)}" if preds else "")
            + ("" if steady is None else f"; steady error (noise-free RMS) {sig(steady, 3)}"))


def method_table(summary: dict) -> list[str]:
    """The table of a run or compare: per method its cost rate, the standard deviation over
    the seeds (only with two seeds or more: one seed has none), the predicted cost rate and
    the RMS errors (only the columns some method has a value in: never "n/a" or "None")."""
    stats = {n: m for n, m in summary["methods"].items() if "cost_rate" in m}
    many = len(summary.get("seeds") or []) > 1
    predicted = any(m["cost_rate"].get("predicted") is not None for m in stats.values())
    any_pred_e = any(b is not None for m in stats.values()
                     for b in (m["rms_e"].get("predicted") or []))
    head = (f"{'method':>10s} {'cost rate':>12s}" + (f" {'(std)':>9s}" if many else "")
            + (f" {'predicted':>10s}" if predicted else "")
            + ("   rms e (sim / pred)" if any_pred_e else "   rms e"))
    lines = [head]
    for name, m in summary["methods"].items():
        if "skipped" in m:
            lines.append(f"{name:>10s}   skipped: {m['skipped']}")
            continue
        if name not in stats:
            lines.append(f"{name:>10s}   {m.get('note', 'no statistics')}")
            continue
        c = m["cost_rate"]
        row = f"{name:>10s} {sig(c['mean'], 4, 12)}"
        if many:
            row += f" {sig(c['std'], 3, 9)}"
        if predicted:
            pred = c.get("predicted")
            row += f" {'-' if pred is None else sig(pred, 4):>10s}"
        lines.append(f"{row}   {_rms_cell(m)}")
        sep = m.get("min_separation")
        if m.get("formation_error_rms"):
            worst = max(m["formation_error_rms"], key=m["formation_error_rms"].get)
            lines.append(f"{'':>10s}   formation error RMS (window) worst edge {worst} "
                         f"{sig(m['formation_error_rms'][worst], 3)} m"
                         + ("" if sep is None else
                            f"; closest approach {sig(sep['m'], 3)} m (vehicles "
                            f"{sep['vehicles'][0]} and {sep['vehicles'][1]} at t = "
                            f"{sep['time_s']:.4g} s, seed {sep['seed']})"))
    return lines


def stationarity_line(summary: dict) -> str | None:
    """The stationarity note in one line: the window, when the slowest mode settles, the T
    that gives stationary figures and, where predicted, the expected cost rate over this
    window (None when the window is stationary)."""
    note = summary.get("stationarity_note")
    if not note:
        return None
    lo, hi = summary["stats_window_s"]
    window = ", ".join(f"{n} {sig(m['cost_rate']['predicted_window'], 4)}"
                       for n, m in summary["methods"].items()
                       if (m.get("cost_rate") or {}).get("predicted_window") is not None)
    settles, at_least = summary.get("settling_time_s"), summary.get("stationary_T_s")
    if settles is None or at_least is None:      # a summary without the figures
        head = f"note: {note.split('; run at least')[0]}"
    else:
        head = (f"note: the window [{lo:.3g}, {hi:.3g}) s is not stationary (the slowest "
                f"mode settles in {settles:.3g} s; run T >= {at_least:.3g} s)")
    return head + (f"; expected over this window: {window}" if window else "")


def links_line(method: str, m: dict) -> str | None:
    """What the acoustic links did in a method's run (None without links): the links and
    their settings, and the age of the newest message a receiver holds, mean (predicted)
    and worst over the window, the worst receiver-sender pair's."""
    net, ages = m.get("network"), m.get("age_of_information")
    if not net:
        return None
    line = (f"links: {method}: {net['links']} links, a message every {net['period']:g} s, "
            f"{net['latency']:g} s on the way, {net['loss']:.0%} lost "
            f"({net.get('loss_model', 'independent')}), receiver {net['receiver']}")
    pairs = [a for per in (ages or {}).values() for a in per.values()]
    if pairs:
        worst = max(pairs, key=lambda a: a["mean"])
        pred = worst.get("predicted_mean")
        line += (f"; age of information up to {sig(worst['mean'], 3)} s on average"
                 + ("" if pred is None else f" (predicted {sig(pred, 3)})")
                 + f", {sig(max(a['max'] for a in pairs), 3)} s at worst")
    return line


def summary_notes(summary: dict) -> list[str]:
    """The notes under the table, one line each: saturation, the acoustic links, why a
    prediction is missing, the full-information bound, the stationarity of the window."""
    lines = [line for name, m in summary["methods"].items()
             if (line := saturation_line(name, m.get(
                 "actuator_saturation_fraction_per_vehicle")))]
    lines += [line for name, m in summary["methods"].items()
              if (line := links_line(name, m))]
    notes = {m.get("prediction_note") for m in summary["methods"].values()} - {None}
    lines += [f"note: {note}" for note in sorted(notes)]
    if summary.get("cost_rate_full_information") is not None:
        line = (f"full-information bound (every state known, the same cost) "
                f"{sig(summary['cost_rate_full_information'], 4)}")
        if summary.get("price_of_decentralization") is not None:
            pred = summary.get("price_of_decentralization_predicted")
            line += (f"; price of decentralization J_distributed / J_centralized "
                     f"{summary['price_of_decentralization']:.4f}"
                     + ("" if pred is None else f" (predicted {pred:.4f})"))
        lines.append(line)
    lines += [line for line in (stationarity_line(summary),)
              if line]
    return lines


def print_summary(summary: dict, out: Path, note: str = "") -> int:
    """Print the summary table and where the files are; the exit status: 0, or 130 / 143
    for a run stopped by SIGINT / SIGTERM (after one line saying what was kept, ending
    with ``note``: an earlier result kept beside it)."""
    print(f"scenario {summary['scenario']}: T = {summary['T']} s, h = {summary['h']} s, "
          f"{summary['steps']} steps, seeds {summary['seeds']}, "
          f"noise convention '{summary['noise_convention']}', statistics over "
          f"t in [{summary['stats_window_s'][0]:.3g}, {summary['stats_window_s'][1]:.3g}) s")
    kinds: dict[str, list[str]] = {}
    for key, entry in summary.get("fmus", {}).items():
        kinds.setdefault(entry.get("kind", "python"), []).append(key)
    if "native" in kinds:
        print("FMUs: native " + ", ".join(kinds["native"])
              + ("; pythonfmu " + ", ".join(kinds["python"]) if kinds.get("python") else ""))
    masters = summary.get("master") or {}
    if "native" in masters.values():
        print("master: compiled (C) step loop" + ("" if len(set(masters.values())) == 1 else
              " for " + ", ".join(m for m, k in masters.items() if k == "native")
              + "; Python for the others"))
    for line in (summary.get("design") or {}).get("printout", []):
        print(line)                          # what [design] chose, and the path check
    for line in method_table(summary):
        print(line)
    for line in summary_notes(summary):
        print(line)
    paced = summary.get("realtime")
    if paced:
        drift = paced["wall_s"] / paced["planned_s"] - 1 if paced["planned_s"] else 0.0
        print(f"real time x{paced['factor']:g}: {paced['wall_s']:.2f} s of wall clock for "
              f"{paced['planned_s']:.2f} s planned ({100 * drift:+.2f} %), "
              f"{paced['overruns']} overrun(s), worst lateness "
              f"{1e3 * paced['worst_lateness_s']:.1f} ms")
    rrd = summary["rrd"]["path"]
    if rrd:
        print(f"wrote {rrd} and {out / 'summary.json'}; wall time {summary['wall_s']:.1f} s")
        print(f"open it with: {viewer_command()} {shlex.quote(rrd)}")
    if summary.get("interrupted"):
        from ..interrupt import EXIT_STATUS
        by = summary["interrupted_by"]
        kept = (f"{rrd} (traces to t = {summary['time_reached_s']:.6g} s)" if rrd
                else "no traces (stopped before the first steps)")
        print(f"auv-cosim: interrupted by {by} at t = {summary['time_reached_s']:.6g} s of "
              f"{summary['T']} s: kept {kept} and {out / 'summary.json'} (marked "
              f"\"interrupted\": true; statistics over the seeds that completed)"
              + (f"; {note}" if note else ""), file=sys.stderr)
        return EXIT_STATUS.get(by, 130)
    return 0
