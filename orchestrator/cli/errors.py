"""How ``auv-cosim`` fails: every error a user can cause (a bad scenario, an impossible
design, an FMU that refuses a call, an unwritable folder) is one line naming the problem,
exit status 2; a bug of ours says so and where its traceback was written."""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from plant_model.linalg_checks import ModelError

from ..cosim.instance import CosimError
from ..cosim.native import NativeBuildError
from ..cosim.system import AlgebraicLoopError
from ..exit_status import USAGE
from ..interop.common import ExportError
from ..interrupt import EXIT_STATUS, Interrupted
from ..outputs import OutputFolderError
from ..scenario import ScenarioError

__all__ = ["USER_ERRORS", "UsageError", "run_command"]


class UsageError(RuntimeError):
    """Bad input found by a command itself (not by the scenario loader or an FMU)."""


# what bad input raises: printed as one line, exit status 2 (USAGE; every status:
# orchestrator.exit_status)
USER_ERRORS = (ScenarioError, ModelError, CosimError, ExportError, AlgebraicLoopError,
               OutputFolderError, UsageError, NativeBuildError)


def run_command(args: argparse.Namespace) -> int:
    """Run the parsed command (``args.func``); its exit status, every failure mapped to one
    line on stderr and a status: bad input 2, SIGINT 130, a bug of ours 2 with a log. When
    the command had an earlier result in its output folder, one more line says it was kept
    (the note :func:`orchestrator.outputs.staged_output` adds to the exception)."""
    try:
        return args.func(args)
    except USER_ERRORS as exc:
        print(f"auv-cosim {args.command}: error: {exc}", file=sys.stderr)
        _notes(exc)
        return USAGE
    except OSError as exc:          # an output folder that is a file, unwritable, full, ...
        where = f" {exc.filename}" if exc.filename else ""
        print(f"auv-cosim {args.command}: error: cannot write or read{where}: "
              f"{exc.strerror or exc}", file=sys.stderr)
        _notes(exc)
        return USAGE
    except Interrupted as exc:      # a stop during the design, before any step
        print(f"auv-cosim {args.command}: {exc}", file=sys.stderr)
        _notes(exc)
        return EXIT_STATUS[exc.signal]
    except KeyboardInterrupt as exc:
        print("interrupted", file=sys.stderr)
        _notes(exc)
        return 130
    except Exception as exc:        # a bug of ours, not bad input: say so, keep the traceback
        log = _write_bug_report(args)
        print(f"auv-cosim {args.command}: internal error (a bug in auv-cosim, not in your "
              f"input): {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
              f"; traceback in {log}; please report it with that file", file=sys.stderr)
        _notes(exc)
        return USAGE


def _notes(exc: BaseException) -> None:
    """The notes of ``exc`` (an earlier result kept), one line each."""
    for note in getattr(exc, "__notes__", ()):
        print(note, file=sys.stderr)


def _write_bug_report(args: argparse.Namespace) -> str:
    """Write the current exception's traceback, the command line and the versions to a log
    file (``$AUV_COSIM_CACHE/../logs`` or ``~/.cache/auv-cosim/logs``; else the temporary
    folder); its path, or a note that none could be written."""
    import platform
    import tempfile
    import time
    import traceback
    text = (f"auv-cosim {' '.join(sys.argv[1:])}\n{time.strftime('%Y-%m-%d %H:%M:%S')}  "
            f"python {platform.python_version()} on {platform.platform()}\n\n"
            + traceback.format_exc())
    cache = os.environ.get("AUV_COSIM_CACHE")
    base = Path(cache).parent if cache else Path.home() / ".cache" / "auv-cosim"
    for folder in (base / "logs", Path(tempfile.gettempdir())):
        try:
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f"auv-cosim-{args.command}-{time.strftime('%Y%m%d-%H%M%S')}-" \
                            f"{os.getpid()}.log"
            path.write_text(text, encoding="utf-8")
            return str(path)
        except OSError:
            continue
    return "(no log: no writable folder)"
