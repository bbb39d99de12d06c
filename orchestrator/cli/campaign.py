"""``auv-cosim campaign``: Monte Carlo runs and parameter sweeps from a spec file (the work
is :mod:`orchestrator.campaign`'s)."""
from __future__ import annotations

import argparse

from .args import _count
from .common import add_fmu_options

__all__ = ["add_campaign", "cmd_campaign"]


def cmd_campaign(args: argparse.Namespace) -> int:
    from ..campaign.runner import run_campaign
    return run_campaign(args.spec, args.out, scheduler=args.scheduler, workers=args.workers,
                        engine=args.engine, fmus=args.fmus,
                        progress=False if args.quiet else None)


def add_campaign(sub: argparse._SubParsersAction) -> None:
    """The ``campaign`` command's sub-parser."""
    sp = sub.add_parser("campaign", help="Monte Carlo runs and parameter sweeps from a spec "
                                         "file, on local worker processes or a Dask cluster")
    sp.add_argument("spec", help="campaign spec (.toml): base scenario, seeds, [sweep] axes")
    sp.add_argument("--scheduler", help="address of a running Dask scheduler "
                                        "(tcp://host:port); default: a local cluster")
    sp.add_argument("--workers", type=_count, help="worker processes of the local cluster "
                                                   "(default: one per core)")
    sp.add_argument("--out", help="output folder (default: out/campaign_<name>)")
    sp.add_argument("--engine", choices=("fmu", "numpy"),
                    help="fmu: the three FMUs; numpy: the closed loop vectorised over seeds "
                         "where it applies (default: the spec's, else fmu)")
    add_fmu_options(sp)
    sp.set_defaults(func=cmd_campaign)
