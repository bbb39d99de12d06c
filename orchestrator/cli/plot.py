"""``auv-cosim plot``: static figures of a run folder (the work is
:mod:`orchestrator.plotting`'s)."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from .errors import UsageError

__all__ = ["add_plot", "cmd_plot"]


def cmd_plot(args: argparse.Namespace) -> int:
    """Write the figures into a staging folder and swap it in as --out (default
    ``RUN_DIR/figures``) when every figure is written
    (:func:`orchestrator.outputs.staged_output`)."""
    from ..outputs import staged_output
    from ..plotting import RunFolderError, folder_interruption, parse_formats, plot_run
    dest = Path(args.out) if args.out else Path(args.run_dir) / "figures"
    run_dir = Path(os.path.realpath(args.run_dir))
    if Path(os.path.realpath(dest)) in (run_dir, *run_dir.parents):
        raise UsageError(f"--out {dest} holds the run folder {args.run_dir} (the figures' "
                         "folder is replaced whole): choose a folder inside it or elsewhere")
    try:
        formats = parse_formats(args.format)
        if not (Path(args.run_dir) / "summary.json").is_file():
            plot_run(args.run_dir, dest, formats)   # says why in one line, writes nothing
        with staged_output(dest, "plot", force=None) as st:
            written = [st.shown(p) for p in plot_run(args.run_dir, st.path, formats)]
    except (RunFolderError, ValueError) as exc:
        error = UsageError(str(exc))
        for note in getattr(exc, "__notes__", ()):
            error.add_note(note)                    # the earlier figures kept
        raise error from None
    if not args.quiet:
        for path in written:
            print(path)
    note = folder_interruption(args.run_dir)
    if note:                  # the figures' titles say it too
        print(f"note: {args.run_dir}: {note} (each figure's title says so)")
    # a compare of plants writes one subfolder per plant: name the folder that holds them all
    where = Path(os.path.commonpath([p.parent for p in written])) if written else dest
    print(f"wrote {len(written)} files into {where}")
    return 0


def add_plot(sub: argparse._SubParsersAction) -> None:
    """The ``plot`` command's sub-parser."""
    sp = sub.add_parser("plot", help="static figures of a run folder (PNG, SVG, PDF): the "
                                     "paper's figures 2-7, or a fleet's paths and errors")
    sp.add_argument("run_dir", metavar="RUN_DIR",
                    help="a folder written by 'auv-cosim run' or 'compare'")
    sp.add_argument("--out", help="output folder (default: RUN_DIR/figures)")
    sp.add_argument("--format", default="png,svg",
                    help="comma-separated formats from png, svg, pdf (default: png,svg)")
    sp.set_defaults(func=cmd_plot)
