"""``auv-cosim``: build the FMUs, run, compare, plot, validate and benchmark.

Every error a user can cause (a bad scenario, an impossible design, an FMU that
refuses a call) is printed as one line naming the problem, with exit status 2.

- :mod:`.entry`: :func:`main` and :func:`console` (the ``auv-cosim`` command);
- :mod:`.parser`: the argument parser, assembled from the command modules' sub-parsers;
- :mod:`.run` (run, compare, envelope), :mod:`.fmus` (build, validate, export),
  :mod:`.campaign`, :mod:`.plot`, :mod:`.bench`: the commands;
- :mod:`.common`: the scenario options, the options of the commands that run FMUs, the
  printed summary; :mod:`.args`: argument types; :mod:`.errors`: failures and exit status.
"""
from .args import parse_floats, parse_seeds, positive_metres
from .common import viewer_command
from .entry import console, main
from .errors import UsageError
from .parser import build_parser

__all__ = ["UsageError", "build_parser", "console", "main", "parse_floats", "parse_seeds",
           "positive_metres", "viewer_command"]
