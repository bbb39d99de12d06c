"""The ``auv-cosim`` console script and ``python -m orchestrator``: start what a command
will need in parallel before importing the command line (the .rrd writer of ``run`` and
``compare``, :func:`orchestrator.recording.background.prestart`), then run it
(:func:`orchestrator.cli.entry.console`)."""
from __future__ import annotations

import sys

__all__ = ["console"]

#: the commands that write a .rrd through the background writer
WRITING = ("run", "compare")


def console() -> None:
    """The ``auv-cosim`` command (see :func:`orchestrator.cli.entry.console`)."""
    argv = sys.argv[1:]
    if argv and argv[0] in WRITING and not {"-h", "--help"} & set(argv):
        from ..recording.background import prestart
        prestart()
    from .entry import console as run
    run()
