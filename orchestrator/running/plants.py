"""``auv-cosim compare --what plants``: the same estimator and controller FMUs on the linear
``remus100`` and on the nonlinear ``remus100-6dof`` (docs/remus100-6dof.md).

Each plant is a full run of the scenario (per-vehicle deployment) in its own subfolder,
``<out>/remus100/`` and ``<out>/remus100-6dof/``, with its own .rrd and summary.json; the
combined ``<out>/summary.json`` holds both under ``methods`` (named by the plant), each
with the straight-leg and turn figures of :mod:`orchestrator.analysis.tracking_segments`
(``max_error``, ``actuator_saturation_fraction``, ...), and ``plants``: per plant its folder
and recording. Both plants' statistics are over one window, the later of the two plants'
own (``stats_window_s``, each plant's ``window_start_s``), as in any compare.
"""
from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from plant_model.vehicle_models import plants_of

from ..atomic import write_text_atomically
from ..numbers import sig
from ..scenario import Scenario

__all__ = ["PLANTS", "compare_plants", "plant_table"]

#: the vehicle models compared, linear first
PLANTS = plants_of("remus100")


def compare_plants(sc: Scenario, seeds: Sequence[int], out: Path, *, progress: bool,
                   log: Callable[[str], None], plants: Sequence[str] = PLANTS
                   ) -> dict[str, Any]:
    """Run ``sc`` once per vehicle model of ``plants`` and combine the summaries.

    Parameters
    ----------
    sc : Scenario
        A fleet scenario of REMUS 100 vehicles, per-vehicle deployment.
    seeds : sequence of int
        Noise seeds (the same for both plants: the same current and sensor noise).
    out : Path
        Output folder; each plant writes into ``out / <model>``.
    progress, log
        As :func:`orchestrator.running.simulate`.
    plants : sequence of str, optional
        Vehicle models, default :data:`PLANTS`.

    Returns
    -------
    dict[str, Any]
        The combined summary (also ``out / summary.json``).
    """
    from .compare import simulate

    variants = {model: sc.with_vehicle_model(model) for model in plants}
    k0 = _common_window(variants, out, log)
    summaries: dict[str, dict[str, Any]] = {}
    for model, variant in variants.items():
        log(f"plant {model}:")
        summaries[model] = simulate(variant, [sc.estimator], seeds, out / model,
                                    progress=progress, log=log, window_from_step=k0)
        if summaries[model].get("interrupted"):
            break
    first = summaries[plants[0]]
    combined = {k: v for k, v in first.items() if k not in ("methods", "rrd", "timing")}
    combined["methods"] = {}
    combined["plants"] = {}
    for model, s in summaries.items():
        (method,) = s["methods"].values()
        combined["methods"][model] = {**method, "plant": model}
        combined["plants"][model] = {"folder": model, "rrd": s.get("rrd"),
                                     "wall_s": s.get("wall_s")}
    # a stop ends the plant it stopped (the last one run): its signal and time
    stopped = next((m for m, s in summaries.items() if s.get("interrupted")), None)
    combined["interrupted"] = stopped is not None
    combined["interrupted_by"] = None if stopped is None else summaries[stopped][
        "interrupted_by"]
    combined["interrupted_plant"] = stopped
    combined["time_reached_s"] = (summaries[stopped]["time_reached_s"] if stopped
                                  else combined["T"])
    combined["scenario"] = sc.name
    write_text_atomically(out / "summary.json", json.dumps(combined, indent=2) + "\n")
    return combined


def _common_window(variants: dict[str, Scenario], out: Path,
                   log: Callable[[str], None]) -> int:
    """The first sample of the window both plants' statistics share: the latest of their
    own (their predictions, computed here once and kept for the runs: the design model's
    loop, the same for both unless the scenario says otherwise)."""
    from .compare import common_window
    from .setup import Method
    from .systems import make_setup
    preds = []
    for model, variant in variants.items():
        setup = make_setup(variant, out / model / "fmus", [Method.of(variant)])
        setup.log = log
        preds.append(setup.predictions(Method.of(variant)))
    return common_window(preds)


def plant_table(summary: dict[str, Any]) -> list[str]:
    """The lines ``compare --what plants`` prints: per plant its cost rate, maximum and RMS
    errors on straight legs and in turns, the saturated share, and its recording."""
    lo, hi = summary["stats_window_s"]
    lines = [f"scenario {summary['scenario']}: T = {summary['T']} s, h = {summary['h']} s, "
             f"seeds {summary['seeds']}, window t in [{lo:.3g}, {hi:.3g}) s; errors |e_i| "
             "in m; turns: the leader turning faster than 0.02 rad/s (-: none in the window)",
             f"{'plant':>14s} {'cost rate':>10s} {'max':>7s} {'max str.':>9s} "
             f"{'max turns':>9s} {'rms str.':>9s} {'rms turns':>9s} {'saturated':>9s}"]

    def f(v: Any, fmt: str | None = None) -> str:    # "-": e.g. no turn in the window
        return "-" if v is None else sig(v, 3) if fmt is None else format(v, fmt)
    for name, m in summary["methods"].items():
        if "cost_rate" not in m:
            lines.append(f"{name:>14s}   {m.get('note', 'no statistics')}")
            continue
        lines.append(f"{name:>14s} {sig(m['cost_rate']['mean'], 4, 10)} {f(m['max_error']):>7s} "
                     f"{f(m['max_error_straight']):>9s} {f(m['max_error_turns']):>9s} "
                     f"{f(m['rms_error_straight']):>9s} {f(m['rms_error_turns']):>9s} "
                     f"{f(m['actuator_saturation_fraction'], '.1%'):>9s}")
    for name, p in summary["plants"].items():
        rrd = (p.get("rrd") or {}).get("path")
        if rrd:
            lines.append(f"{name}: {rrd}")
    return lines
