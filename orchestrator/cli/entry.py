"""The ``auv-cosim`` command: parse the command line, run the command, exit."""
from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from .errors import run_command
from .parser import build_parser

__all__ = ["console", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "seed", None) is not None and not 0 <= args.seed <= 2**31 - 1:
        parser.error(f"--seed {args.seed}: seeds must be from 0 to 2^31 - 1 "
                     "(a 32-bit FMI Integer)")
    return run_command(args)


def console() -> None:
    """The ``auv-cosim`` command: :func:`main`, then leave without tearing the interpreter
    down. Every file is closed and every temporary folder removed by then; what remains is
    freeing numpy, scipy and the FMU libraries module by module (about 0.2 s), and
    pythonfmu 0.7's library-unload hook, which touches freed memory (see
    docs/known-problems.md)."""
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
