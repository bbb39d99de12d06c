"""A run folder read back: its ``summary.json``, the scalar series of its ``.rrd``, the
methods it recorded and, for fleets, the units of the vehicle model.

A run folder is what ``auv-cosim run`` or ``auv-cosim compare`` writes: ``summary.json``
and ``<scenario>.rrd`` (the traces of the first seed of every method).
"""
from __future__ import annotations

import json
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["RunData", "RunFolderError", "folder_interruption", "interruption_note", "load_run"]

#: series of the paper layout whose presence marks it (component 1 of the error)
_PAPER_PROBE = "error/1/{m}"
#: series of the fleet layout whose presence marks it (vehicle 1's error)
_FLEET_PROBE = "vehicles/1/error/{m}"
_BUILTIN = re.compile(r"^built-in scenario '(?P<name>[^']+)'$")


class RunFolderError(ValueError):
    """A folder that cannot be plotted: not a run folder, no or a broken summary.json, a
    missing or unreadable .rrd, no recorded traces (the message is one line naming it)."""


@dataclass(frozen=True, eq=False)
class RunData:
    """What the figures need from a run folder.

    Attributes
    ----------
    folder : Path
        The run folder.
    summary : dict
        ``summary.json``.
    rrd : Path
        The recording.
    methods : tuple[str, ...]
        Recorded methods in the summary's order (skipped methods left out); the recording's
        colours are ``method_color(methods)``.
    scalars : dict
        Every scalar series of the recording (:func:`orchestrator.recording.read_rrd_scalars`).
    fleet : bool
        True for the per-vehicle fleet layout, False for the paper layout.
    units : dict[str, str]
        Units of the fleet vehicle model's components by name (states, inputs, outputs),
        when the scenario could be loaded and its names match the recording; else empty
        (axes then say "model units").
    error_names : tuple[str, ...]
        Fleet: the component names of a vehicle's error (e.g. ``n``, ``e``, ``d``), from
        the recording's series names; () for the paper layout.
    """

    folder: Path
    summary: dict[str, Any]
    rrd: Path
    methods: tuple[str, ...]
    scalars: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    fleet: bool
    units: dict[str, str]
    error_names: tuple[str, ...] = ()
    #: what the figures' titles name beside the scenario: the plant of a ``compare --what
    #: plants`` subfolder, the architectures of a per-vehicle compare, the FMU kind
    label: str = ""

    @property
    def scenario(self) -> str:
        """The scenario's name."""
        return str(self.summary.get("scenario", "?"))

    @property
    def interruption(self) -> str | None:
        """:func:`interruption_note` of the run: what every figure's title says of a run
        stopped by a signal (None: the run finished)."""
        return interruption_note(self.summary)

    @property
    def seed(self) -> int | None:
        """The seed whose traces the recording holds."""
        return self.summary.get("rrd", {}).get("traces_of_seed")

    def n_vehicles(self) -> int:
        """Number of vehicles in a fleet recording (0 for the paper layout)."""
        m = self.methods[0]
        n = 0
        while f"vehicles/{n + 1}/error/{m}" in self.scalars:
            n += 1
        return n

    def components(self, root: str) -> int:
        """Number of components i of ``root/{i}/...`` in the paper layout (e.g. ``error``)."""
        m = self.methods[0]
        i = 0
        while any(f"{root}/{i + 1}/{m}{suffix}" in self.scalars for suffix in ("", "/true")):
            i += 1
        return i


def interruption_note(summary: dict[str, Any]) -> str | None:
    """One line saying that a run was stopped by a signal (summary.json's ``interrupted``,
    ``interrupted_by``, ``time_reached_s``): when, and what its traces and statistics then
    hold; None for a run that finished.

    Parameters
    ----------
    summary : dict
        A run's (or a compare of plants') summary.json.

    Returns
    -------
    str or None
        E.g. "interrupted run: stopped by SIGINT at t = 41.2 s of 3000 s; the traces end
        there, the statistics are over the seeds that completed".
    """
    if summary.get("interrupted") is not True:
        return None
    sig = summary.get("interrupted_by") or "a signal"
    reached, T = summary.get("time_reached_s"), summary.get("T")
    when = ""
    if isinstance(reached, (int, float)):
        when = f" at t = {reached:.6g} s" + (f" of {T:.6g} s" if isinstance(T, (int, float))
                                             else "")
    plant = summary.get("interrupted_plant")
    return (f"interrupted run: stopped by {sig}{when}"
            + (f" (plant {plant})" if plant else "")
            + "; the traces end there, the statistics are over the seeds that completed")


def folder_interruption(folder: str | Path) -> str | None:
    """:func:`interruption_note` of a folder's summary.json (None when it has none or the
    run finished)."""
    summary = _read_summary_file(Path(folder))
    return interruption_note(summary) if isinstance(summary, dict) else None


def _read_summary_file(folder: Path) -> Any:
    """summary.json of a folder, None if there is none or it is not JSON."""
    try:
        return json.loads((folder / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _read_summary(folder: Path) -> dict[str, Any]:
    path = folder / "summary.json"
    if not folder.exists():
        raise RunFolderError(f"{folder} does not exist")
    if not folder.is_dir():
        raise RunFolderError(f"{folder} is not a folder (give the run folder that "
                             "auv-cosim run or compare wrote)")
    if not path.is_file():
        raise RunFolderError(f"{folder} is not a run folder: it has no summary.json (written by "
                             "auv-cosim run or compare)")
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RunFolderError(f"{path} is not a run summary (not valid JSON: {exc})") from None
    except OSError as exc:
        raise RunFolderError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if (not isinstance(summary, dict) or not isinstance(summary.get("methods"), dict)
            or not isinstance(summary.get("rrd"), dict)):
        raise RunFolderError(f"{path} is not a run summary (no 'methods' and 'rrd' entries)")
    return summary


def _rrd_path(folder: Path, summary: dict[str, Any]) -> Path:
    """The .rrd of the run: the file named in the summary, looked up in ``folder`` (so a
    moved or copied run folder still plots)."""
    named = summary["rrd"].get("path")
    if not named:
        raise RunFolderError(f"{folder / 'summary.json'}: the run recorded no traces (it was "
                             "stopped before its first step): nothing to plot")
    rrd = folder / Path(str(named)).name
    if not rrd.is_file():
        raise RunFolderError(f"{rrd} is missing: the run folder's recording (named in "
                             "summary.json) is not there")
    return rrd


def _read_scalars(rrd: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    from orchestrator.recording import read_rrd_scalars
    try:
        with warnings.catch_warnings():     # rerun warns about a file without its footer
            warnings.simplefilter("ignore")
            return read_rrd_scalars(rrd)
    except (RuntimeError, ValueError, OSError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        first = first.replace(f"Failed to read RRD file at {rrd}: ", "")
        raise RunFolderError(f"{rrd} cannot be read as a recording: {first}") from None


def _methods(summary: dict[str, Any], scalars: dict[str, Any], rrd: Path) -> tuple[
        tuple[str, ...], bool]:
    """Recorded methods (summary order) and whether the layout is the fleet one; checks that
    the recording is this run's (every method that ran is in it, with the summary's number
    of samples)."""
    layouts = [(probe, fleet, tuple(m for m in summary["methods"] if probe.format(m=m) in scalars))
               for probe, fleet in ((_PAPER_PROBE, False), (_FLEET_PROBE, True))]
    probe, fleet, found = next((lay for lay in layouts if lay[2]), layouts[0])
    if not found:
        raise RunFolderError(f"{rrd} holds no traces of the summary's methods "
                             f"({', '.join(summary['methods']) or 'none'}): not this run's "
                             "recording?")
    ran = [m for m, v in summary["methods"].items()
           if isinstance(v, dict) and v.get("seeds_completed", 1) and "skipped" not in v]
    missing = [m for m in ran if m not in found]
    if missing:
        raise RunFolderError(f"{rrd} holds no traces of {', '.join(missing)}, which "
                             "summary.json says ran: not this run's recording?")
    steps, stride = summary["rrd"].get("recorded_steps"), summary["rrd"].get(
        "recorded_every_steps", 1)
    rows = len(scalars[probe.format(m=found[0])][0])
    if isinstance(steps, int) and isinstance(stride, int) and stride > 0 \
            and rows != -(-steps // stride):
        raise RunFolderError(f"{rrd} holds {rows} samples per series but summary.json says "
                             f"{-(-steps // stride)}: not this run's recording?")
    return found, fleet


def _error_names(rrd: Path, method: str) -> tuple[str, ...]:
    """Component names of a fleet vehicle's error (``n``, ``e``, ``d``), from the series
    names of the recording; () if it has none."""
    from orchestrator.recording import read_rrd_series_lines
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lines = read_rrd_series_lines(rrd)
    except (RuntimeError, ValueError, OSError):
        return ()
    recorded = lines.get(f"vehicles/1/error/{method}", ((), ()))[0]
    return tuple(n.removeprefix(f"{method} ") for n in recorded)


def _fleet_units(summary: dict[str, Any], error_names: tuple[str, ...]) -> dict[str, str]:
    """Units of the vehicle model by component name, from the scenario the summary names
    (a built-in name or a .toml file), if it still loads and its output names are the
    recorded error names; else {}."""
    source = str(summary.get("source", ""))
    m = _BUILTIN.match(source)
    spec = m.group("name") if m else source
    if not spec or (not m and not Path(spec).is_file()):
        return {}
    try:
        from orchestrator.scenario import load_scenario
        sc = load_scenario(spec)
        if sc.fleet is None:
            return {}
        model = sc.fleet.models[0]
    except Exception:       # a file changed or gone since the run: no units, not an error
        return {}
    if error_names != tuple(model.output_names):
        return {}          # the scenario file changed since the run: do not guess
    units: dict[str, str] = {}
    for n, u in (*zip(model.state_names, model.state_units),
                 *zip(model.input_names, model.input_units),
                 *zip(model.output_names, model.output_units)):
        units.setdefault(n, u)
    return units


def load_run(folder: str | Path) -> RunData:
    """Read a run folder for plotting.

    Parameters
    ----------
    folder : str or Path
        A folder written by ``auv-cosim run`` or ``auv-cosim compare``.

    Returns
    -------
    RunData

    Raises
    ------
    RunFolderError
        If the folder does not exist or is not a run folder (no summary.json, or one that is
        not a run summary), the run recorded no traces, or its .rrd is missing, unreadable or
        holds none of the summary's methods.
    """
    folder = Path(folder)
    summary = _read_summary(folder)
    rrd = _rrd_path(folder, summary)
    scalars = _read_scalars(rrd)
    methods, fleet = _methods(summary, scalars, rrd)
    error_names = _error_names(rrd, methods[0]) if fleet else ()
    units = _fleet_units(summary, error_names) if fleet else {}
    return RunData(folder=folder, summary=summary, rrd=rrd, methods=methods, scalars=scalars,
                   fleet=fleet, units=units, error_names=error_names,
                   label=_label(summary, methods))


def _label(summary: dict[str, Any], methods: tuple[str, ...]) -> str:
    """The title's label of a run: its plant (a vehicle model), the architecture of each
    method of a per-vehicle run, its FMU kind when native."""
    parts = []
    if summary.get("plant"):
        parts.append(f"plant {summary['plant']}")
    if summary.get("deployment") == "per-vehicle":
        archs = [summary["methods"][m].get("architecture") for m in methods]
        if any(archs):
            parts.append(f"{summary['deployment']}, "
                         + " vs ".join(f"{m}: {a}" if m != a else a
                                       for m, a in zip(methods, archs)))
    if summary.get("fmu_kind", "python") != "python":
        parts.append(f"{summary['fmu_kind']} FMUs")
    return "; ".join(parts)


def plant_folders(folder: str | Path) -> list[tuple[str, Path]] | None:
    """(plant, subfolder) of a ``compare --what plants`` folder, None for another folder."""
    folder = Path(folder)
    summary = _read_summary_file(folder)
    plants = summary.get("plants") if isinstance(summary, dict) else None
    if not isinstance(plants, dict):
        return None
    return [(name, folder / str(p.get("folder", name))) for name, p in plants.items()]
