"""``auv-cosim``: build the FMUs, run, compare, plot, validate and benchmark.

Every error a user can cause (a bad scenario, an impossible design, an FMU that
refuses a call) is printed as one line naming the problem, with exit status 2.

- :mod:`.launch`: the console script (starts the .rrd writer, then :mod:`.entry`);
- :mod:`.entry`: :func:`main` and :func:`console` (the ``auv-cosim`` command);
- :mod:`.parser`: the argument parser, assembled from the command modules' sub-parsers;
- :mod:`.run` (run, compare, envelope), :mod:`.fmus` (build, validate, export),
  :mod:`.campaign`, :mod:`.plot`, :mod:`.bench`: the commands;
- :mod:`.common`: the scenario options, the options of the commands that run FMUs, the
  printed summary; :mod:`.args`: argument types; :mod:`.errors`: failures and exit status.
"""
from __future__ import annotations

import importlib
from typing import Any

__all__ = ["UsageError", "build_parser", "console", "main", "parse_floats", "parse_seeds",
           "positive_metres", "viewer_command"]

#: where each name lives; imported on first use, so that :mod:`.launch` (the console
#: script) starts the .rrd writer before numpy and scipy are imported
_HOMES = {"parse_floats": "args", "parse_seeds": "args", "positive_metres": "args",
          "viewer_command": "common", "console": "entry", "main": "entry",
          "UsageError": "errors", "build_parser": "parser"}


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
