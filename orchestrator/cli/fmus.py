"""``auv-cosim build``, ``validate`` and ``export``: the FMUs themselves, for this project
and for other tools."""
from __future__ import annotations

import argparse
from pathlib import Path

from controller_fmu.regulator import TRACKING_MODES
from estimator_fmu.registry import ESTIMATOR_MODES

from ..outputs import file_stem, staged_output
from .common import add_force_option, add_scenario_options, scenario_of
from .errors import UsageError

__all__ = ["add_build", "add_export", "add_validate", "cmd_build", "cmd_export", "cmd_validate"]


#: the tail of ``build``'s default folder, ``out/<scenario>[_<system>]_fmus``
BUILD_TAIL = "fmus"


def cmd_build(args: argparse.Namespace) -> int:
    """Build the scenario's FMUs into --out (default ``out/<scenario>[_<system>]_fmus``,
    never the checkout's tracked ``fmus/``); the default folder also gets ``README.md``,
    every variable of these FMUs (the committed ``fmus/README.md`` is the same text for
    the paper scenario)."""
    from ..atomic import write_text_atomically
    from ..running import build
    from ..running.fmus import fmu_readme
    from ..running.naming import default_out, run_identity
    sc = scenario_of(args)
    lines = []
    with staged_output(args.out or default_out(sc, BUILD_TAIL), "build",
                       identity=run_identity(sc, "build"), force=args.force) as st:
        paths = build(sc, st.path)
        if args.out is None:
            write_text_atomically(st.path / "README.md", fmu_readme(sc))
        for k, p in paths.items():
            lines.append(f"{k:>18s}: {st.shown(p)} ({p.stat().st_size} bytes)")
        if sc.deployment == "per-vehicle":
            lines.append("(no cross-check references for the per-vehicle FMUs: they are "
                         "written for the stacked deployment's three FMUs)")
        elif not args.no_crosscheck:
            from ..interop.crosscheck import write_crosscheck
            from ..running import scenario_config, scenario_system
            written = write_crosscheck(paths, scenario_config(sc), st.path / "crosscheck",
                                       system=scenario_system(sc))
            lines.append(f"cross-check references (<Model>_in.csv, _ref.csv, _ref.opt) for "
                         f"{', '.join(written)} in {st.shown(st.path / 'crosscheck')}")
    print("\n".join(lines))                  # after the swap: every path named exists
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    """Write the scenario's FMUs with an OSP system, an SSP archive or as native FMUs, then
    print, per host that runs them, its command (:mod:`orchestrator.interop.hosts`)."""
    sc = scenario_of(args)
    platforms: tuple[str, ...] = ()
    notes: list[str] = []
    if args.platforms is not None and args.format != "native":
        raise UsageError("--platforms is for export native only")
    if args.format == "native":
        from ..cosim.native import NativeBuildError, compiler
        from ..cosim.platforms import resolve_platforms
        try:
            compiler()                      # no C compiler: say so before any folder exists
            # a requested platform without its compiler: the same, nothing written
            platforms, notes = resolve_platforms(
                None if args.platforms is None
                else [p.strip() for p in args.platforms.split(",") if p.strip()])
        except (NativeBuildError, ValueError) as exc:
            raise UsageError(str(exc)) from None
    from ..interop.hosts import export_hint, host_commands
    from ..running.naming import default_export_out, run_identity
    with staged_output(args.out or default_export_out(sc, args.format), "export",
                       identity=run_identity(sc, f"export {args.format}"),
                       force=args.force) as st:
        out = st.out
        if args.format == "native":
            from ..cosim.native import NativeBuildError
            from ..interop.native import export_native
            try:
                paths = export_native(sc, st.path, platforms=platforms)
            except NativeBuildError as exc:
                raise UsageError(str(exc)) from None
            fmus = [p.name for p in paths.values() if p.suffix == ".fmu"]
            native = [f for f in fmus if f.endswith("Native.fmu")]
            kept = [f for f in fmus if f not in native]
            lines = [f"native FMUs for scenario {sc.name} in {out}: {', '.join(native)}"
                     + (f" (and, not linear, needing Python: {', '.join(kept)})" if kept
                        else "")
                     + f"; OSP system {paths['system'].name}, SSP archive "
                       f"{paths['ssp'].name}",
                     f"binaries for {', '.join(platforms)}",
                     *notes]
            hosts = host_commands("native", st.shown(st.path), T=sc.T, h=sc.h,
                                  system=st.shown(paths["system"]),
                                  ssp=st.shown(paths["ssp"]), needs_python=bool(kept))
        elif args.format == "osp":
            from ..interop.osp import export_osp
            paths = export_osp(sc, st.path)
            lines = [f"OSP system for scenario {sc.name} in {out}: {paths['system'].name}, "
                     + ", ".join(p.name for k, p in paths.items() if k != "system")]
            hosts = host_commands("osp", st.shown(st.path), T=sc.T, h=sc.h,
                                  system=st.shown(paths["system"]))
        else:
            from ..interop.ssp import export_ssp
            path = st.shown(export_ssp(sc, st.path / f"{file_stem(sc.name)}.ssp"))
            lines = [f"SSP archive for scenario {sc.name}: {path}"]
            hosts = host_commands("ssp", st.shown(st.path), T=sc.T, h=sc.h, ssp=path)
    lines.append(export_hint(hosts))
    print("\n".join(lines))
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    import tempfile

    from fmpy.validation import validate_fmu

    from ..running import build
    if args.fmu_files:
        import zipfile
        paths = {p.stem: p for p in (Path(x) for x in args.fmu_files)}
        missing = [str(p) for p in paths.values() if not p.is_file()]
        if missing:
            raise UsageError(f"FMU file(s) not found: {', '.join(missing)}")
        not_zip = [str(p) for p in paths.values() if not zipfile.is_zipfile(p)]
        if not_zip:
            raise UsageError(f"not an FMU (an FMU is a zip archive): {', '.join(not_zip)}")
        tmp = None
    else:
        tmp = tempfile.TemporaryDirectory(prefix="auv_validate_")
        paths = build(scenario_of(args), Path(tmp.name))
    bad = 0
    for name, p in paths.items():
        problems = validate_fmu(str(p))
        bad += len(problems)
        verdict = "no problem" if not problems else f"{len(problems)} problem(s)"
        print(f"{name:>10s}: {p.name}: {verdict}")
        for prob in problems:
            print(f"            - {prob}")
    if tmp:
        tmp.cleanup()
    return 1 if bad else 0


def add_build(sub: argparse._SubParsersAction) -> None:
    """The ``build`` command's sub-parser."""
    sp = sub.add_parser("build", help="build the scenario's FMUs (default into "
                                      f"out/<scenario>_{BUILD_TAIL})")
    add_scenario_options(sp)
    sp.add_argument("--out", help="output folder (default: out/<scenario>[_<system>]_"
                                  f"{BUILD_TAIL}, with a README.md of every variable)")
    sp.add_argument("--tracking", choices=TRACKING_MODES,
                    help="the controller FMU's default tracking law (default: scenario's)")
    sp.add_argument("--no-crosscheck", action="store_true",
                    help="skip the FMI cross-check reference files (500 steps of the closed loop)")
    add_force_option(sp)
    sp.set_defaults(func=cmd_build)


def add_export(sub: argparse._SubParsersAction) -> None:
    """The ``export`` command's sub-parser."""
    sp = sub.add_parser("export", help="the FMUs and a system file for other tools: an OSP "
                                       "system (libcosim) or an SSP archive (fmpy, SSP tools); "
                                       "native: compiled FMUs of the design, no Python needed, "
                                       "with both system files")
    sp.add_argument("format", choices=("osp", "ssp", "native"),
                    help="osp: the FMUs and an OSP system structure file (libcosim); ssp: "
                         "an SSP archive of the FMUs (fmpy, SSP tools); native: compiled FMUs "
                         "of the design (no Python needed) with both system files")
    add_scenario_options(sp)
    sp.add_argument("--tracking", choices=TRACKING_MODES, help="the controller's tracking law")
    sp.add_argument("--estimator", choices=ESTIMATOR_MODES, help="the estimator's mode")
    sp.add_argument("--seed", type=int, help="noise seed written as the plant's initial value")
    sp.add_argument("--out", help="output folder (default: out/<scenario>_<format>)")
    sp.add_argument("--platforms", metavar="LIST",
                    help="native only: the platforms the native FMUs carry binaries for, "
                         "comma-separated, of linux64, win64, aarch64-linux (default: every "
                         "one whose compiler is installed; one asked for without its "
                         "compiler is an error)")
    add_force_option(sp)
    sp.set_defaults(func=cmd_export)


def add_validate(sub: argparse._SubParsersAction) -> None:
    """The ``validate`` command's sub-parser."""
    sp = sub.add_parser("validate", help="fmpy validate the FMUs (built afresh, or given)")
    add_scenario_options(sp, run=False)
    sp.add_argument("fmu_files", metavar="fmus", nargs="*",
                    help=".fmu files to validate instead of building")
    sp.set_defaults(func=cmd_validate)
