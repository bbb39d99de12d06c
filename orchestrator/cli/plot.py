"""``auv-cosim plot``: static figures of a run folder (the work is
:mod:`orchestrator.plotting`'s)."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from .errors import UsageError

__all__ = ["add_plot", "cmd_plot"]


def cmd_plot(args: argparse.Namespace) -> int:
    from ..plotting import RunFolderError, folder_interruption, parse_formats, plot_run
    try:
        formats = parse_formats(args.format)
        written = plot_run(args.run_dir, args.out, formats)
    except (RunFolderError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    if not args.quiet:
        for path in written:
            print(path)
    note = folder_interruption(args.run_dir)
    if note:                  # the figures' titles say it too
        print(f"note: {args.run_dir}: {note} (each figure's title says so)")
    # a compare of plants writes one subfolder per plant: name the folder that holds them all
    where = Path(os.path.commonpath([p.parent for p in written])) if written else args.out
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
