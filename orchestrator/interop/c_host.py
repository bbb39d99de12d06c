"""The system file of the C host (orchestrator/interop/native_host/c_host.c) from an exported
OSP system.

``python -m orchestrator.interop.c_host OSP_SYSTEM_XML OUT_DIR`` unzips every FMU the OSP
system names into ``OUT_DIR/<Model>/`` and writes ``OUT_DIR/system.txt``: one ``fmu`` line
per simulator, its initial values (``real``, ``int``), every connection and, as
``record`` lines, every Real output of every simulator (the CSV's columns, in this order).
The C host then runs it with no Python: ``c_host OUT_DIR/system.txt STEPS H OUT_CSV``.
"""
from __future__ import annotations

import argparse
import sys
import zipfile
from collections.abc import Sequence
from pathlib import Path

from lxml import etree

__all__ = ["C_HOST_SOURCE", "OSP_NS", "main", "write_c_host_system_from_osp"]

#: the C host's source (C99: libc, libdl, libm; its system file format: README.md beside it)
C_HOST_SOURCE = Path(__file__).resolve().with_name("native_host") / "c_host.c"

OSP_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"


def _q(tag: str) -> str:
    return f"{{{OSP_NS}}}{tag}"


def write_c_host_system_from_osp(system_xml: Path | str, out_dir: Path | str) -> Path:
    """Unzip the FMUs of an OSP system and write the C host's system file for it.

    Parameters
    ----------
    system_xml : Path or str
        An ``OspSystemStructure.xml`` (its FMUs' sources relative to its folder).
    out_dir : Path or str
        Where the FMUs are unzipped and ``system.txt`` is written (created if missing).

    Returns
    -------
    Path
        ``out_dir/system.txt``.

    Raises
    ------
    ValueError
        On an initial value the C host cannot set (only Real and Integer; a String
        equal to the FMU's start value is left out, as it is already set), or a
        connection naming a variable the FMU lacks.
    """
    from fmpy import read_model_description

    system_xml = Path(system_xml)
    out = Path(out_dir).resolve()
    out.mkdir(parents=True, exist_ok=True)
    root = etree.parse(str(system_xml)).getroot()
    lines: list[str] = []
    variables: dict[str, dict[str, tuple[int, str, str]]] = {}
    unzipped: dict[Path, tuple[Path, object]] = {}
    for sim in root.iter(_q("Simulator")):
        name, fmu = sim.get("name"), (system_xml.parent / sim.get("source")).resolve()
        if fmu not in unzipped:
            folder = out / fmu.stem
            with zipfile.ZipFile(fmu) as z:
                z.extractall(folder)
            unzipped[fmu] = (folder, read_model_description(str(fmu)))
        folder, md = unzipped[fmu]
        variables[name] = {v.name: (v.valueReference, v.type, v.causality)
                           for v in md.modelVariables}
        lines.append(f"fmu {name} {md.coSimulation.modelIdentifier} {md.guid} {folder}")
        for iv in sim.iter(_q("InitialValue")):
            var = iv.get("variable")
            (value_el,) = list(iv)
            kind = etree.QName(value_el).localname
            if kind == "String" and value_el.get("value") == _start(md, var):
                continue            # the FMU's own value (a native FMU's, fixed at export)
            if kind not in ("Real", "Integer"):
                raise ValueError(f"{name}.{var}: a {kind} initial value that differs from the "
                                 "FMU's start value, which the C host cannot set (Real and "
                                 "Integer only)")
            vr = variables[name][var][0]
            value = value_el.get("value")
            lines.append(f"real {name} {vr} {float(value)!r}" if kind == "Real"
                         else f"int {name} {vr} {int(value)}")
    for con in root.iter(_q("VariableConnection")):
        (a, b) = [(v.get("simulator"), v.get("name")) for v in con.iter(_q("Variable"))]
        try:
            lines.append(f"connect {a[0]} {variables[a[0]][a[1]][0]} "
                         f"{b[0]} {variables[b[0]][b[1]][0]}")
        except KeyError as exc:
            raise ValueError(f"connection {a} -> {b}: no variable {exc}") from None
    for name, vs in variables.items():
        lines += [f"record {name} {vr}" for vr, typ, caus in vs.values()
                  if caus == "output" and typ == "Real"]
    path = out / "system.txt"
    path.write_text("\n".join(lines) + "\n")
    return path


def _start(md: object, var: str) -> str | None:
    """The start value of ``var`` in a model description read by fmpy (None if none)."""
    return next((v.start for v in md.modelVariables if v.name == var), None)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m orchestrator.interop.c_host OSP_SYSTEM_XML OUT_DIR``."""
    ap = argparse.ArgumentParser(prog="python -m orchestrator.interop.c_host",
                                 description="write the C host's system file (orchestrator/"
                                             "interop/native_host/c_host.c) for an OSP system")
    ap.add_argument("system", help="OspSystemStructure.xml (of auv-cosim export native)")
    ap.add_argument("out", help="folder for the unzipped FMUs and system.txt")
    args = ap.parse_args(argv)
    try:
        path = write_c_host_system_from_osp(args.system, args.out)
    except (OSError, ValueError, zipfile.BadZipFile, etree.XMLSyntaxError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
