"""The commands that run an export in other hosts: one text per host, in one place.

``auv-cosim export osp|ssp|native`` prints, after writing, for every host that takes what it
wrote, a shell command (or a short script fed to the venv's Python) that runs the exported
system over the scenario's horizon and writes the traces to ``<out>_results/``.
docs/other-tools.md shows the same text for the paper scenario (``tests/test_host_commands.py``
checks that the docs equal :func:`host_commands` and runs the docs' text as written).

Every command is meant to be run from the checkout (``.venv/bin/python``,
``orchestrator/interop/native_host/c_host.c``). What each host needs, found on this machine:

- fmpy 0.3's ``fmpy.ssp.simulation.simulate_ssp`` ignores the archive's DefaultExperiment and
  parameter bindings: without arguments it runs 1 s with a step of stop_time / 100, so
  ``stop_time=300`` alone asks for 3 s steps, which the FMUs (designed for one step h)
  refuse with fmi2Discard ("fmi2DoStep failed with status 2"). The command passes
  ``stop_time``, ``step_size`` and the bindings (:func:`orchestrator.interop.ssp.
  fmpy_parameter_set`).
- libcosim through libcosimpy (PyPI) runs in the venv's Python; time in nanoseconds.
- the ``cosim`` program (open-simulation-platform/cosim-cli) is not on PyPI: Linux and
  Windows builds come with its GitHub releases; its default duration is 1 s.
- ecos ships in the ecospy wheel (``ecospy/binaries/ecos``, perhaps without the run bit;
  Debian needs ``libtbb12``).
- a host without Python of its own (cosim, ecos) loads pythonfmu FMUs only with libpython
  preloaded and the venv named (``LD_PRELOAD``, ``PYTHONEXECUTABLE``; docs/other-tools.md).
- the C host (orchestrator/interop/native_host/c_host.c) takes native FMUs only; its system
  file is written by ``python -m orchestrator.interop.c_host`` from the OSP system.
"""
from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path

__all__ = ["HOSTS", "Host", "export_hint", "host_commands", "results_dir"]

#: in a subshell, before a host without Python starts: the venv's libpython preloaded and
#: the venv named (pythonfmu FMUs need both)
_PYTHON_ENV = (" export LD_PRELOAD=\"$(.venv/bin/python -c 'import sysconfig as s; "
               "print(s.get_config_var(\"LIBDIR\") + \"/\" + "
               "s.get_config_var(\"INSTSONAME\"))')\"\n"
               " export PYTHONEXECUTABLE=\"$PWD/.venv/bin/python\"\n")


@dataclass(frozen=True)
class Host:
    """A host that runs an export, and the text of its command.

    Attributes
    ----------
    key : str
        Short name (``fmpy``, ``libcosimpy``, ``cosim``, ``ecos``, ``c-host``).
    title : str
        What it is, one line (printed above the command as a comment).
    formats : tuple[str, ...]
        The exports it runs (``osp``, ``ssp``, ``native``).
    template : str
        The command, with ``{fields}`` filled by :func:`host_commands`.
    tested : bool
        Whether the tests run it here (the ``cosim`` program is not installable here).
    """

    key: str
    title: str
    formats: tuple[str, ...]
    template: str
    tested: bool = True


HOSTS: tuple[Host, ...] = (
    Host("fmpy", "fmpy's SSP runner (fmpy.ssp.simulation.simulate_ssp) in the venv's Python",
         ("ssp", "native"),
         "mkdir -p {results_sh}\n"
         ".venv/bin/python - <<'EOF'\n"
         "from fmpy.ssp.simulation import simulate_ssp\n"
         "from fmpy.util import write_csv\n"
         "from orchestrator.interop.ssp import fmpy_parameter_set\n"
         "ssp = {ssp_py}\n"
         "# fmpy ignores the archive's stop time, step and bindings: pass them\n"
         "result = simulate_ssp(ssp, stop_time={T}, step_size={h},\n"
         "                      parameter_set=fmpy_parameter_set(ssp))\n"
         "write_csv({fmpy_csv_py}, result)\n"
         "EOF"),
    Host("libcosimpy", "libcosim (OSP) through libcosimpy in the venv's Python",
         ("osp", "native"),
         ".venv/bin/python - <<'EOF'\n"
         "from libcosimpy.CosimExecution import CosimExecution\n"
         "from libcosimpy.CosimLogging import CosimLogLevel, log_output_level\n"
         "from libcosimpy.CosimObserver import CosimObserver\n"
         "log_output_level(CosimLogLevel.WARNING)\n"
         "execution = CosimExecution.from_osp_config_file({system_py})\n"
         "observer = CosimObserver.create_to_dir({libcosim_py})\n"
         "execution.add_observer(observer)\n"
         "assert execution.simulate_until({T_ns}), 'libcosim failed'  # ns: {T} s\n"
         "EOF"),
    Host("cosim", "libcosim's command line, `cosim` of open-simulation-platform/cosim-cli "
                  "(not on PyPI: Linux and Windows builds with its GitHub releases)",
         ("osp", "native"),
         "{env_open}cosim run {system_sh} --duration {T} --output-dir {results_sh}/cosim"
         "{env_close}",
         tested=False),
    Host("ecos", "the ecos engine (C++, its CLI from the ecospy wheel; Debian needs libtbb12)",
         ("ssp", "native"),
         "ECOS=\"$(.venv/bin/python -c 'import ecospy, pathlib; "
         "print(pathlib.Path(ecospy.__file__).parent / \"binaries\" / \"ecos\")')\"\n"
         "chmod +x \"$ECOS\"  # the wheel may not set the run bit\n"
         "mkdir -p {results_sh}/ecos\n"
         "(SSP={ssp_abs_sh}\n"
         "{env_export}"
         " cd {results_sh}/ecos && \"$ECOS\" simulate "
         "--path \"$SSP\" --stopTime {T} --stepSize {h} --noParallel)"),
    Host("c-host", "a C host with no Python (orchestrator/interop/native_host/c_host.c: libc, "
         "libdl, libm)",
         ("native",),
         "mkdir -p {results_sh}/c_host\n"
         "cc -O2 -std=c99 -I\"$(.venv/bin/python -c 'import fmpy, os; "
         "print(os.path.join(os.path.dirname(fmpy.__file__), \"c-code\"))')\" \\\n"
         "   -o {results_sh}/c_host/c_host orchestrator/interop/native_host/c_host.c -ldl -lm\n"
         ".venv/bin/python -m orchestrator.interop.c_host {system_sh} {results_sh}/c_host\n"
         "{results_sh}/c_host/c_host {results_sh}/c_host/system.txt {steps} {h} "
         "{results_sh}/c_host.csv"),
)


def _absolute_sh(path: Path) -> str:
    """``path`` for the shell, made absolute with ``$PWD`` if it is relative."""
    if path.is_absolute():
        return shlex.quote(str(path))
    quoted = shlex.quote(str(path))
    return f'"$PWD/{path}"' if quoted == str(path) else '"$PWD/"' + quoted


def results_dir(export_dir: Path | str) -> Path:
    """Where the hosts' commands write their traces: ``<export folder>_results``."""
    p = Path(export_dir)
    return p.with_name(p.name + "_results")


def host_commands(fmt: str, export_dir: Path | str, *, T: float, h: float,
                  system: Path | str | None = None, ssp: Path | str | None = None,
                  needs_python: bool = True) -> list[tuple[Host, str]]:
    """The hosts that run an export, each with its command filled in.

    Parameters
    ----------
    fmt : str
        ``osp``, ``ssp`` or ``native``.
    export_dir : Path or str
        The export's folder, as the user names it (relative to the checkout or absolute).
    T, h : float
        The scenario's horizon and step, s.
    system : Path or str or None, optional
        The OSP system file (``osp``, ``native``).
    ssp : Path or str or None, optional
        The SSP archive (``ssp``, ``native``).
    needs_python : bool, optional
        Whether some FMU is a pythonfmu one (hosts without Python then preload libpython,
        and the C host is left out).

    Returns
    -------
    list[tuple[Host, str]]
        (host, command) in :data:`HOSTS` order.
    """
    results = results_dir(export_dir)
    steps = int(round(T / h))
    fields = {"T": repr(float(T)), "h": repr(float(h)), "steps": str(steps),
              "T_ns": f"{int(round(T * 1e9)):_d}",
              "results_sh": shlex.quote(str(results)),
              "fmpy_csv_py": repr(str(results / "fmpy.csv")),
              "libcosim_py": repr(str(results / "libcosim")),
              "env_open": "(" + _PYTHON_ENV.lstrip() + " " if needs_python else "",
              "env_close": ")" if needs_python else "",
              "env_export": _PYTHON_ENV if needs_python else ""}
    for name, value in (("system", system), ("ssp", ssp)):
        fields[f"{name}_sh"] = shlex.quote(str(value)) if value is not None else ""
        fields[f"{name}_py"] = repr(str(value)) if value is not None else ""
        fields[f"{name}_abs_sh"] = "" if value is None else _absolute_sh(Path(value))
    out = []
    for host in HOSTS:
        if fmt not in host.formats or (host.key == "c-host" and needs_python):
            continue
        if ("{system" in host.template and system is None) or \
                ("{ssp" in host.template and ssp is None):
            continue
        out.append((host, host.template.format(**fields)))
    return out


def export_hint(commands: list[tuple[Host, str]]) -> str:
    """The text ``export`` prints: every host's command under a comment line naming it.

    Parameters
    ----------
    commands : list[tuple[Host, str]]
        From :func:`host_commands`.

    Returns
    -------
    str
        ``run it from the checkout with any of:`` then, per host, ``# <title>`` (and
        ``(not tested here)`` for the untested ones) and the command.
    """
    lines = ["run it from the checkout with any of:"]
    for host, text in commands:
        lines.append(f"# {host.title}" + ("" if host.tested else " (not tested here)"))
        lines.append(text)
    return "\n".join(lines)
