"""The ``auv-cosim`` argument parser: each command's module adds its own sub-parser."""
from __future__ import annotations

import argparse

from . import bench, campaign, fmus, plot, run
from .common import add_quiet_option

__all__ = ["build_parser"]

# the commands in the order that --help lists them
COMMANDS = (fmus.add_build, run.add_run, run.add_compare, run.add_envelope,
            campaign.add_campaign, fmus.add_export, plot.add_plot, fmus.add_validate,
            bench.add_bench)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="auv-cosim",
        description="Optimal consensus tracking control of AUVs (Yuan, Zhang, Zhou) as three "
                    "FMI 2.0 co-simulation FMUs coupled on fmpy, traced to Rerun.")
    sub = p.add_subparsers(dest="command", required=True)
    for add in COMMANDS:
        add(sub)
    for sp in sub.choices.values():       # every command takes --quiet, meaning the same
        if "--quiet" not in sp._option_string_actions:
            add_quiet_option(sp)
    return p
