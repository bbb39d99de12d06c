"""Static figures of a run folder with matplotlib (``auv-cosim plot RUN_DIR``), for reports and
papers where the Rerun viewer is not an option.

A run folder (``summary.json`` and ``<scenario>.rrd``, written by ``auv-cosim run`` or
``auv-cosim compare``) is read back with the public .rrd reader
(:mod:`orchestrator.recording.reader`) and drawn:

- paper layout: the paper's figures 2-7, ``error-i``, ``state-i`` and ``control-i`` for each
  component, the methods overlaid in the recording's colours (:mod:`.paper`);
- fleet layout: ``fleet-paths`` (leader and vehicles in the north-east plane) and
  ``fleet-errors`` (each vehicle's tracking-error norm against time) (:mod:`.fleet`).

The title of every figure of a run stopped by a signal says so (:mod:`.run_folder`,
``interruption_note``).
Each figure is written as PNG, SVG and/or PDF, atomically and byte for byte the same for the
same run (:mod:`.save`). Modules: :mod:`.run_folder` (:func:`load_run`), :mod:`.figure`
(shared style), :mod:`.paper`, :mod:`.fleet`, :mod:`.save` (:func:`plot_run`). Importing
this package imports matplotlib (never pyplot); the CLI imports it only for ``plot``.
"""
from __future__ import annotations

from .figure import PlotFigure, deterministic_style
from .run_folder import RunData, RunFolderError, folder_interruption, load_run
from .save import DEFAULT_FORMATS, FORMATS, build_figures, parse_formats, plot_run, save_figure

__all__ = [
    "DEFAULT_FORMATS",
    "FORMATS",
    "PlotFigure",
    "RunData",
    "RunFolderError",
    "build_figures",
    "deterministic_style",
    "folder_interruption",
    "load_run",
    "parse_formats",
    "plot_run",
    "save_figure",
]
