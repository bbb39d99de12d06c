"""Build the figures of a run folder and write them: :func:`plot_run`, the formats and their
deterministic, atomic writing."""
from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from pathlib import Path

from orchestrator.atomic import temporary_sibling
from orchestrator.outputs import file_stem, make_folder

from .figure import PlotFigure, deterministic_style
from .run_folder import RunData, RunFolderError, load_run, plant_folders

__all__ = ["DEFAULT_FORMATS", "FORMATS", "build_figures", "parse_formats", "plot_run",
           "save_figure"]

#: File formats ``auv-cosim plot`` can write.
FORMATS: tuple[str, ...] = ("png", "svg", "pdf")
#: Written when no ``--format`` is given.
DEFAULT_FORMATS: tuple[str, ...] = ("png", "svg")

#: Metadata that makes the vector files the same on every call (no creation date).
_METADATA: dict[str, dict[str, str | None]] = {
    "png": {"Software": "auv-cosim (matplotlib)"},
    "svg": {"Date": None, "Creator": "auv-cosim (matplotlib)"},
    "pdf": {"CreationDate": None, "ModDate": None, "Creator": "auv-cosim (matplotlib)",
            "Producer": "auv-cosim (matplotlib)"},
}


def parse_formats(text: str) -> tuple[str, ...]:
    """``"png,svg"`` -> ``("png", "svg")``, checked against :data:`FORMATS`.

    Parameters
    ----------
    text : str
        Comma-separated formats (case and spaces ignored).

    Returns
    -------
    tuple[str, ...]
        The formats, each once, in the given order.

    Raises
    ------
    ValueError
        If a format is unknown or none is given (one line naming it).
    """
    picked: list[str] = []
    for part in text.split(","):
        f = part.strip().lower().lstrip(".")
        if f and f not in picked:
            picked.append(f)
    unknown = [f for f in picked if f not in FORMATS]
    if unknown or not picked:
        what = f"{', '.join(unknown)} is not one of" if unknown else "give one or more of"
        raise ValueError(f"--format {text!r}: {what} {', '.join(FORMATS)} "
                         "(comma-separated, e.g. png,pdf)")
    return tuple(picked)


def build_figures(run: RunData) -> list[PlotFigure]:
    """Every figure of a run: figures 2-7 for the paper layout, the fleet figures for a
    fleet; the title of each says when the run was interrupted (its last two lines:
    :attr:`RunData.interruption`). Call it inside :func:`deterministic_style` for the
    package's fixed style."""
    if run.fleet:
        from .fleet import fleet_figures
        figures = fleet_figures(run)
    else:
        from .paper import paper_figures
        figures = paper_figures(run)
    note = run.interruption
    if note:                     # two lines: the narrowest figure is 7.5 inches wide
        note = note.replace("; ", "\n", 1)
        for pf in figures:
            title = pf.figure.get_suptitle()
            pf.figure.suptitle(f"{title}\n{note}" if title else note, fontsize=10)
    return figures


def save_figure(pf: PlotFigure, out: Path, formats: Sequence[str]) -> list[Path]:
    """Write one figure in each format as ``out/<name>.<format>``, each file through a
    temporary sibling renamed into place.

    Parameters
    ----------
    pf : PlotFigure
    out : Path
        Destination folder (created if needed).
    formats : Sequence[str]
        Formats from :data:`FORMATS`.

    Returns
    -------
    list[Path]
        The files written.
    """
    written = []
    umask = os.umask(0o022)
    os.umask(umask)
    for fmt in formats:
        path = out / f"{pf.name}.{fmt}"
        with temporary_sibling(path) as tmp:
            with open(tmp, "wb") as fh:
                pf.figure.savefig(fh, format=fmt, metadata=_METADATA[fmt])
            os.chmod(tmp, 0o666 & ~umask)    # as open() would (the temporary file is 0600)
        written.append(path)
    return written


def plot_run(folder: str | Path, out: str | Path | None = None,
             formats: Sequence[str] = DEFAULT_FORMATS) -> list[Path]:
    """Write the figures of a run folder.

    Parameters
    ----------
    folder : str or Path
        A folder written by ``auv-cosim run`` or ``auv-cosim compare``.
    out : str, Path or None, optional
        Where to write; default ``<folder>/figures``.
    formats : Sequence[str], optional
        Formats from :data:`FORMATS` (default PNG and SVG).

    Returns
    -------
    list[Path]
        The files written, figure by figure.

    Raises
    ------
    RunFolderError
        If the folder cannot be plotted (see :func:`load_run`).
    ValueError
        If a format is unknown.
    OutputFolderError
        If the output folder is a file, under a file or cannot be written.
    """
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or not formats:
        raise ValueError(f"formats {list(formats)!r}: expected some of {', '.join(FORMATS)}")
    dest = Path(out) if out is not None else Path(folder) / "figures"
    plants = plant_folders(folder)
    if plants is not None:                # compare --what plants: each plant's run, its name
        written: list[Path] = []          # in every title, its figures in a subfolder
        for name, sub in plants:
            if (sub / "summary.json").exists():
                written += _plot_one(load_run(sub), dest / file_stem(name), formats,
                                     f"plant {name}")
        if not written:
            raise RunFolderError(f"{folder}: no plant's run finished (no subfolder holds a "
                                 "run summary)")
        return written
    return _plot_one(load_run(folder), dest, formats)


def _plot_one(run: RunData, dest: Path, formats: Sequence[str], label: str = "") -> list[Path]:
    if label:
        run = dataclasses.replace(run, label="; ".join(filter(None, [label, run.label])))
    dest = make_folder(dest)
    written: list[Path] = []
    with deterministic_style():
        for pf in build_figures(run):
            written += save_figure(pf, dest, formats)
            pf.figure.clear()
    return written
