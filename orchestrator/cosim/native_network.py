"""The native (C) AuvNetwork FMU: one vehicle's acoustic inbox without Python.

Its C model (fmu_common/native/network_fmu.c, on the shared FMI plumbing fmu_core.c and
numpy's generator numpy_random.c) steps the links as plant_model.acoustic.links does: the
same send steps, arrival steps, loss draws (numpy's ``Generator.random()`` of the
PCG64 seeded ``[seed, 1000000 + key]``, independent or Gilbert-Elliott as
plant_model.acoustic.link_models draws them), schedule, modem range and receiver (held,
or propagated by M). The native FMU is made from the pythonfmu FMU it replaces:

- its ``modelDescription.xml`` is the pythonfmu FMU's (the same variables in the same order,
  names, causalities, units, start values, descriptions and ModelStructure), with the
  value references counted per type (Reals 0.., Integers 0..: pythonfmu counts them
  together), the co-simulation capabilities of a native build and its own GUID and model
  identifier ``AuvNetworkNative``;
- its generated ``native_model.h`` holds the link table (the value references of each
  link's variables), the names and start values, and ``QCAP``: how many messages a link
  may have in flight, the most over the start values and the parameter sets given (every
  network component of a fleet), so a component with a longer latency is served; a
  latency beyond it is refused at initialization, naming the link.

A host addresses the variables by name, so it swaps one for the other by file name only.
"""
from __future__ import annotations

import json
import math
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from lxml import etree

from fmu_common.interface import element_names
from plant_model.acoustic.auv_network_slave import link_layout

from .native_build import (
    NATIVE_DIR,
    NativeBuildError,
    compile_fmu,
    native_identity,
    native_model,
)

__all__ = ["NETWORK_C", "native_network_fmu"]

#: the C sources of the native network FMU
NETWORK_C = (NATIVE_DIR / "fmu_core.c", NATIVE_DIR / "network_fmu.c",
             NATIVE_DIR / "numpy_random.c")
NETWORK_H = (NATIVE_DIR / "fmu_core.h", NATIVE_DIR / "network_model.h",
             NATIVE_DIR / "numpy_random.h")
_LAYOUT = ("parameter", "input", "output")


Var = tuple[str, str, str]


def _variables(root: etree._Element) -> tuple[list[Var], list[Var], dict[str, int]]:
    """(name, causality, start) per Real and per Integer, and every name's new value
    reference (counted per type in document order).

    Raises
    ------
    NativeBuildError
        A type other than Real or Integer, an Integer that is not a parameter, or Reals
        that are not parameters, then inputs, then outputs (the layout fmu_core.c serves).
    """
    reals: list[Var] = []
    ints: list[Var] = []
    vr: dict[str, int] = {}
    for sv in root.iterfind("ModelVariables/ScalarVariable"):
        typ = sv[0] if len(sv) else None
        name, causality = sv.get("name"), sv.get("causality")
        if typ is None or typ.tag not in ("Real", "Integer"):
            raise NativeBuildError(f"AuvNetwork variable {name} is neither Real nor Integer")
        if typ.tag == "Integer" and causality != "parameter":
            raise NativeBuildError(f"AuvNetwork variable {name}: an Integer {causality}")
        group = reals if typ.tag == "Real" else ints
        vr[name] = len(group)
        group.append((name, causality, typ.get("start", "0")))
    order = [_LAYOUT.index(c) if c in _LAYOUT else -1 for _, c, _ in reals]
    if -1 in order or order != sorted(order):
        raise NativeBuildError("AuvNetwork: the Real variables are not parameters, inputs, "
                               "outputs in this order")
    return reals, ints, vr


def _capacity(config: Mapping[str, Any], parameter_sets: Iterable[Mapping[str, Any]]) -> int:
    """The most messages in flight on one link, ceil(latency / period) + 1, over the
    configuration's start values and the parameter sets (FMI scalar names)."""
    layout = link_layout(dict(config))
    need = 1
    for values in [{}, *parameter_sets]:
        for p, _, _, st in layout:
            lat = float(values.get(f"{p}.latency", st["latency"]))
            per = float(values.get(f"{p}.period", st["period"]))
            if per > 0.0 and math.isfinite(lat / per) and lat >= 0.0:
                need = max(need, math.ceil(lat / per) + 1)
    return min(need, 1001)


def _header(config: Mapping[str, Any], reals: list[Var], ints: list[Var], vr: dict[str, int],
            qcap: int, guid: str) -> str:
    """native_model.h: sizes, the link table, names and start values (module docstring)."""
    count = {c: sum(1 for _, cc, _ in reals if cc == c) for c in _LAYOUT}
    layout = link_layout(dict(config))
    widths = [sum(n for _, n in fields) for _, _, fields, _ in layout]
    schedule = config.get("schedule")
    G = len(schedule["t"]) if schedule else 0
    has_range = bool(config.get("range"))

    def need(name: str) -> int:
        if name not in vr:
            raise NativeBuildError(f"AuvNetwork: no variable {name} in the modelDescription")
        return vr[name]

    def block(want: list[str]) -> int:
        """The value reference of the first of ``want``, which must follow each other."""
        first = need(want[0])
        if [n for n, _, _ in reals[first:first + len(want)]] != want:
            raise NativeBuildError(f"AuvNetwork: {want[0]} .. {want[-1]} are not contiguous "
                                   "Real variables")
        return first

    rows = []
    for (p, label, fields, _), w in zip(layout, widths):
        tx = block([nm for f, n in fields for nm in element_names(f"{p}.tx.{f}", (n,))])
        rx = block([nm for f, n in fields for nm in element_names(f"{p}.rx.{f}", (n,))])
        block(element_names(f"{p}.M", (w, w)))
        block(element_names(f"{p}.rx0", (w,)))
        stats = [need(f"{p}.{s}") for s in ("age", "delivered", "lost", "in_flight")]
        if stats[0] != rx + w or stats != list(range(rx + w, rx + w + 4)):
            raise NativeBuildError(f"AuvNetwork: the rx outputs of {p} are not contiguous")
        txx = need(f"{p}.tx.x[1]") if has_range and p != "leader" else -1
        up = need(f"{p}.up[1]") if G else -1
        # a bursty link's model row and Gilbert-Elliott parameters (link_models)
        bursty = ([need(f"{p}.{k}") for k in ("loss_model", "p_gb", "p_bg", "loss_good",
                                             "loss_bad")]
                  if config.get("loss_models") else [-1] * 5)
        rows.append(f'    {{"{label}", "{p}", {w}, {int(p == "leader")}, '
                    f'{need(f"{p}.latency")}, {need(f"{p}.period")}, {need(f"{p}.loss")}, '
                    f'{need(f"{p}.offset")}, {need(f"{p}.M[1,1]")}, {need(f"{p}.rx0[1]")}, '
                    f'{tx}, {rx}, {stats[0]}, {stats[1]}, {stats[2]}, {stats[3]}, {txx}, '
                    f'{need(f"{p}.key")}, {up}, {", ".join(str(v) for v in bursty)}}},')
    extra = [f"#define VR_h {need('h')}", f"#define IVR_seed {need('seed')}"]
    if has_range:
        extra += [f"#define VR_range {need('range')}", f"#define VR_x {need('x[1]')}"]
        # without a leader link no link reads H (0: a placeholder the C model compiles with)
        extra.append(f"#define VR_leader_H "
                     f"{need('leader.H[1,1]') if config['leader_size'] else 0}")
    if G:
        extra += [f"#define VR_schedule_t {need('schedule.t[1]')}",
                  f"#define VR_schedule_period {need('schedule.period')}"]
    pos = [int(i) for i in config.get("position_index", [0, 1, 2])] if has_range else [0, 0, 0]

    def strings(xs: list[str]) -> str:
        return ",\n".join(f'    "{x}"' for x in xs) or '    ""'

    return "\n".join([
        "/* generated by auv-cosim (orchestrator/cosim/native_network.py) from the pythonfmu",
        "   AuvNetwork FMU's modelDescription: see fmu_core.h and network_fmu.c */",
        f'#define NATIVE_GUID "{guid}"',
        f"#define NPARR {count['parameter']}", f"#define NIN {count['input']}",
        f"#define NOUT {count['output']}", f"#define NREAL {len(reals)}",
        f"#define NINT {len(ints)}",
        f"#define STEP_VR {need('h')}", "#define START_AT_ZERO 0",
        f"#define NLINKS {len(layout)}", f"#define WMAX {max(widths, default=1)}",
        f"#define QCAP {qcap}", f"#define NGRAPHS {G}", f"#define HAS_RANGE {int(has_range)}",
        *extra,
        '#include "network_model.h"',
        "#ifdef NATIVE_MODEL_TABLES",
        "static const LinkInfo LINKS[NLINKS > 0 ? NLINKS : 1] = {",
        *(rows or ['    {"", "", 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, -1, 0, -1, '
                   '-1, -1, -1, -1, -1},']), "};",
        f"static const int POSITION_INDEX[3] = {{{pos[0]}, {pos[1]}, {pos[2]}}};",
        "static const char *const REAL_NAMES[ALLOC(NREAL)] = {", strings([n for n, _, _ in reals]),
        "};",
        "/* start values of the Real parameters and inputs (outputs: 0) */",
        "static const double REAL_START[ALLOC(NREAL)] = {",
        ",\n".join(f"    {float(s)!r}" for _, _, s in reals) or "    0.0", "};",
        "static const char *const INT_NAMES[ALLOC(NINT)] = {", strings([n for n, _, _ in ints]),
        "};",
        "static const int INT_START[ALLOC(NINT)] = {",
        ",\n".join(f"    {int(s)}" for _, _, s in ints) or "    0", "};",
        "#endif", ""])


def _model_description(root: etree._Element, vr: dict[str, int], model: str,
                       guid: str) -> bytes:
    """The pythonfmu FMU's modelDescription as the native FMU's (module docstring)."""
    md = native_identity(root, model, guid)
    for sv in md.iterfind("ModelVariables/ScalarVariable"):
        sv.set("valueReference", str(vr[sv.get("name")]))
    old = md.find("CoSimulation")
    cs = etree.Element("CoSimulation", modelIdentifier=model, needsExecutionTool="false",
                       canHandleVariableCommunicationStepSize="false",
                       canGetAndSetFMUstate="true", canSerializeFMUstate="true")
    src = etree.SubElement(cs, "SourceFiles")
    for f in NETWORK_C:
        etree.SubElement(src, "File", name=f.name)
    md.replace(old, cs)
    return etree.tostring(md, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def native_network_fmu(fmu: Path | str, out_dir: Path | str,
                       parameter_sets: Iterable[Mapping[str, Any]] = (),
                       platforms: Sequence[str] | None = None) -> Path:
    """The native AuvNetwork FMU, from its built pythonfmu FMU.

    Parameters
    ----------
    fmu : Path or str
        The pythonfmu AuvNetwork FMU (its modelDescription gives the interface and start
        values, its configuration the link layout).
    out_dir : Path or str
        Destination folder; the FMU is ``AuvNetworkNative.fmu``.
    parameter_sets : Iterable[Mapping[str, Any]], optional
        The parameter values (FMI scalar names) of every component that will use it: the
        queue capacity covers their latencies too.
    platforms : Sequence[str] or None, optional
        The platforms it carries binaries for (:func:`compile_fmu`); default the host's.

    Returns
    -------
    Path
        ``AuvNetworkNative.fmu`` in ``out_dir``.

    Raises
    ------
    NativeBuildError
        An interface the C model does not serve, no compiler, or a compiler error.
    """
    model = native_model("network")
    with zipfile.ZipFile(fmu) as z:
        root = etree.fromstring(z.read("modelDescription.xml"))
        config = json.loads(z.read("resources/auv_network_config.json"))
    reals, ints, vr = _variables(root)
    qcap = _capacity(config, list(parameter_sets))
    _header(config, reals, ints, vr, qcap, "")             # an interface it does not serve: now
    return compile_fmu(model, NETWORK_C, NETWORK_H,
                       lambda guid: _header(config, reals, ints, vr, qcap, guid),
                       lambda guid: _model_description(root, vr, model, guid), out_dir,
                       platforms)
