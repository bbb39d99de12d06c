"""Native FMUs: a designed FMU compiled to C, no Python at run time.

Every FMU kind except the acoustic network, the guidance interface and the nonlinear
vehicles is linear once designed (:mod:`fmu_common.native_form`). :func:`form_of` sets up
the pythonfmu slave of a component in this process (from the configuration inside its
built .fmu and the component's parameter values) and asks it for its linear form;
:func:`build_native_fmu` writes the form as an FMI 2.0 co-simulation FMU:

- ``modelDescription.xml``: the slave's inputs and outputs (names, units, direct
  feedthrough), the form's matrices as parameters (structured names, start values from the
  design), ``h``, and ``seed`` (and ``stream``, a vehicle's key) for a noisy plant;
  ``needsExecutionTool="false"``;
- ``sources/``: ``fmu_core.c``/``.h`` (the FMI plumbing shared by every native FMU),
  ``linear_fmu.c``/``linear_model.h`` (the linear system on it) and
  ``numpy_random.c``/``.h`` (fmu_common/native/: numpy's SeedSequence, PCG64 and ziggurat
  normals, so a native plant draws the pythonfmu plant's noise), the generated
  ``native_model.h`` and the FMI 2.0 headers, the .c files listed in the modelDescription;
- ``binaries/linux64/<model>.so``: built with the system C compiler (:data:`CFLAGS`; libc
  and libm only); ``auv-cosim export native`` adds ``binaries/win64/<model>.dll`` and
  ``binaries/aarch64-linux/<model>.so`` where their cross compilers are installed
  (:mod:`orchestrator.cosim.platforms`).

A native FMU does not re-solve the Riccati equations: a design change means exporting
again, or setting the gain and filter parameters. The guidance interface (not linear) has
a C model of its own per FMU: :mod:`orchestrator.cosim.native_guidance`; so has the
acoustic network (``AuvNetworkNative``, :mod:`orchestrator.cosim.native_network`).
"""
from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fmu_common.interface import ArraySpec, element_names
from fmu_common.native_form import NativeForm
from plant_model.linalg_checks import ModelError
from plant_model.vehicle_models import REGISTRY

from .build import FMU_KINDS, GUIDANCE_KINDS
from .native_build import (
    CFLAGS,
    NATIVE_DIR,
    NativeBuildError,
    arrays_model_description,
    compile_fmu,
    compiler,
    native_model,
)
from .native_template import component_slave
from .system import SystemDescription

__all__ = ["CFLAGS", "LINEAR_KINDS", "NATIVE_KINDS", "NONLINEAR_VEHICLE_KINDS", "NativeBuildError",
           "NativeSystem",
           "build_native_fmu", "compile_fmu", "compiler", "form_of", "native_model",
           "native_parameters", "native_specs", "native_system"]

#: the vehicle FMU kinds of the nonlinear models (the registry's)
NONLINEAR_VEHICLE_KINDS = tuple(dict.fromkeys(e.fmu_kind for e in REGISTRY.values()
                                              if e.nonlinear))
#: the kinds whose FMUs are linear once designed, compiled from their linear form (the
#: network, the nonlinear vehicle and the guidance interface are not; with navigation
#: sensors the vehicle and estimator FMUs are not either: the estimator is then the native
#: multi-rate filter, orchestrator.cosim.native_multirate, the vehicle stays pythonfmu)
LINEAR_KINDS = tuple(k for k in FMU_KINDS
                     if k not in ("network", *NONLINEAR_VEHICLE_KINDS, *GUIDANCE_KINDS))
#: the kinds that have a native (C) FMU: the linear ones, the guidance interface
#: (AuvGuidance, AuvAutopilot: a C model each, orchestrator.cosim.native_guidance) and the
#: nonlinear REMUS 100 (AuvRemus6dof, AuvRemus6dofActuated: orchestrator.cosim.native_remus)
#: and the acoustic network (AuvNetwork, orchestrator.cosim.native_network)
NATIVE_KINDS = LINEAR_KINDS + GUIDANCE_KINDS + NONLINEAR_VEHICLE_KINDS + ("network",)
#: the C sources compiled into every linear native FMU (the shared FMI plumbing, the linear
#: system, numpy's generator)
C_SOURCES = (NATIVE_DIR / "fmu_core.c", NATIVE_DIR / "linear_fmu.c",
             NATIVE_DIR / "numpy_random.c")
C_HEADERS = (NATIVE_DIR / "fmu_core.h", NATIVE_DIR / "linear_model.h",
             NATIVE_DIR / "numpy_random.h")

# ------------------------------------------------------------------ the form of a component
def form_of(kind: str, fmu: Path, parameters: Mapping[str, Any]) -> NativeForm:
    """The linear form of a component: its slave set up in this process.

    Parameters
    ----------
    kind : str
        The FMU kind (a key of FMU_KINDS, not "network").
    fmu : Path
        The built pythonfmu FMU (its configuration is read from resources/).
    parameters : Mapping[str, Any]
        The component's parameter values (FMI scalar names), as in the system description.

    Returns
    -------
    NativeForm
        What the native FMU computes.

    Raises
    ------
    ModelError
        If the kind has no native form or the slave's setup fails (its message).
    """
    if kind not in LINEAR_KINDS:
        raise ModelError(f"the {kind} FMU has no native form (it is not linear)")
    with component_slave(kind, fmu, parameters) as slave:
        form = copy.deepcopy(slave.native_form())  # its own arrays: the slave serves on
    if not form.description:                   # pythonfmu's instance attribute is None
        form = dataclasses.replace(form, description=type(slave).description)
    form.check()
    return form


# ------------------------------------------------------------------ interface and files
def native_specs(form: NativeForm) -> list[ArraySpec]:
    """The native FMU's arrays: the roles, h, seed (with noise) and stream (one keyed
    stream), then the slave's inputs and outputs (value references in this order, per
    type)."""
    specs = [ArraySpec(r.name, r.value.shape, "parameter", r.description, start=r.value,
                       unit=r.unit) for r in form.roles]
    specs.append(ArraySpec("h", (), "parameter", "any communication step (a static law)"
                           if form.static else "the communication step the design is for",
                           start=float(form.h), unit="s"))
    if form.nxi:
        specs.append(ArraySpec(
            "seed", (), "parameter", "seed of the noise: numpy's PCG64 seeded by SeedSequence "
            "and its ziggurat normals, the pythonfmu FMU's numbers", start=form.seed,
            type="Integer", min=0, max=2**31 - 1))
    if form.stream is not None:
        specs.append(ArraySpec(
            "stream", (), "parameter", "key of the noise stream (the vehicle's number; the "
            "generator is numpy's default_rng([seed, stream]))", start=form.stream,
            type="Integer", min=0, max=2**31 - 1))
    return specs + list(form.inputs) + list(form.outputs)


def native_parameters(form: NativeForm, base: NativeForm | None = None) -> dict[str, Any]:
    """Scalar parameter values of a form (FMI names), only those that differ from ``base``
    (the form the FMU was built with) if given."""
    out: dict[str, Any] = {}
    ref = {r.name: r.value for r in base.roles} if base is not None else {}
    for r in form.roles:
        names = element_names(r.name, r.value.shape)
        old = ref.get(r.name)
        for i, (nm, v) in enumerate(zip(names, r.value.reshape(-1))):
            if old is None or old.reshape(-1)[i] != v:
                out[nm] = float(v)
    for key, v in (("seed", form.seed if form.nxi else None), ("stream", form.stream)):
        if v is not None and (base is None or getattr(base, key) != v):
            out[key] = int(v)
    return out


def _c_double(v: float) -> str:
    return repr(float(v)) if np.isfinite(v) else "0.0"


def _header(form: NativeForm, guid: str) -> str:
    roles, offset, par = [], 0, []
    index = {}
    row_base = 0          # where the role's row ends start in ModelState.row_end
    for i, r in enumerate(form.roles):
        m = r.matrix
        roles.append(f'    {{"{r.name}", {offset}u, {m.shape[0]}u, {m.shape[1]}u, {r.row0}u, '
                     f'{r.col0}u, {r.sign!r}, {int(r.vector)}, {row_base}u}},')
        par += [_c_double(v) for v in r.value.reshape(-1)]
        offset += r.value.size
        row_base += m.shape[0] + 1
        index[r.key] = i
    names_in = [nm for s in form.inputs for nm in element_names(s.name, s.shape)]
    names_out = [nm for s in form.outputs for nm in element_names(s.name, s.shape)]

    def strings(xs: list[str]) -> str:
        return ",\n".join(f'    "{x}"' for x in xs) or '    ""'

    streams = [f"    {{{int(k is not None)}, {0 if k is None else int(k)}u, {int(c)}u}},"
               for k, c in form.noise_streams]

    lines = [
        "/* generated by auv-cosim (orchestrator/cosim/native.py): sizes, value references,",
        "   start values of one native FMU; see fmu_core.h and linear_fmu.c */",
        f'#define NATIVE_GUID "{guid}"',
        f"#define NQ {form.nq}", f"#define NU {form.nu}", f"#define NY {form.ny}",
        f"#define NXI {form.nxi}", f"#define NPAR {offset}", f"#define NROLES {len(roles)}",
        f"#define NROW_ENDS {row_base}",
        f"#define H_START {float(form.h)!r}", f"#define SEED_START {int(form.seed)}",
        f"#define STREAM_START {int(form.stream or 0)}",
        f"#define NSTREAMS {len(streams)}",
        f"#define HAS_STREAM_PARAM {int(form.stream is not None)}",
        *(f"#define ROLE_{k} {index.get(k, -1)}" for k in
          ("A", "B", "Bo", "b", "F", "C", "D", "c", "G", "q0", "sat")),
        "/* the layout fmu_core.c serves: the entries and h, the inputs, the outputs; seed",
        "   and stream; a system with a state takes only the step h, from t = 0 */",
        "#define NPARR (NPAR + 1)", "#define NIN NU", "#define NOUT NY",
        "#define NREAL (NPARR + NIN + NOUT)",
        "#define NINT ((NXI > 0) + HAS_STREAM_PARAM)",
        "#define STEP_VR (NQ > 0 ? NPAR : -1)", "#define START_AT_ZERO (NQ > 0)",
        '#include "linear_model.h"',
        "#ifdef NATIVE_MODEL_TABLES",
        "static const RoleInfo ROLES[ALLOC(NROLES)] = {", *roles, "};",
        "static const StreamInfo STREAMS[ALLOC(NSTREAMS)] = {",
        *(streams or ["    {0, 0u, 0u},"]), "};",
        "static const double PAR_START[ALLOC(NPAR)] = {",
        "    " + ",\n    ".join(par or ["0.0"]), "};",
        "static const char *const INPUT_NAMES[ALLOC(NU)] = {", strings(names_in), "};",
        "static const char *const OUTPUT_NAMES[ALLOC(NY)] = {", strings(names_out), "};",
        "#endif", ""]
    return "\n".join(lines)


def _model_description(form: NativeForm, model: str, guid: str, T: float, h: float) -> bytes:
    return arrays_model_description(
        native_specs(form), model, guid,
        form.description + " (native C build: the designed matrices, no Python)",
        C_SOURCES, T=T, h=h, variable_step=form.static)


def build_native_fmu(form: NativeForm, model: str, out_dir: Path | str, T: float,
                     h: float | None = None, platforms: Sequence[str] | None = None) -> Path:
    """Write ``<model>.fmu`` into ``out_dir``: modelDescription, sources, binaries.

    Parameters
    ----------
    form : NativeForm
        What the FMU computes, with its start values.
    model : str
        Model identifier (:func:`native_model`).
    out_dir : Path or str
        Destination folder (created if missing); the .fmu is written atomically.
    T : float
        Stop time of the default experiment, s.
    h : float or None, optional
        The system's communication step, the default experiment's step (ecos steps an FMU
        at its default experiment's step); default the form's h.
    platforms : Sequence[str] or None, optional
        The platforms it carries binaries for (:func:`compile_fmu`); default the host's.

    Returns
    -------
    Path
        The linear form's FMU, ``<model>.fmu`` in ``out_dir``.

    Raises
    ------
    NativeBuildError
        No compiler, or the compiler failed (its first error line).
    """
    form.check()
    return compile_fmu(model, C_SOURCES, C_HEADERS, lambda guid: _header(form, guid),
                       lambda guid: _model_description(form, model, guid, T,
                                                       form.h if h is None else h), out_dir,
                       platforms)


@dataclasses.dataclass(frozen=True)
class NativeSystem:
    """A system whose linear components are native FMUs."""

    system: SystemDescription            #: the same wiring, native interfaces and parameters
    fmus: dict[str, Path]                #: FMU key -> .fmu (native, or pythonfmu)
    forms: dict[str, NativeForm]         #: component -> its linear form
    #: the FMU keys whose FMU is native (the linear forms', the guidance interface's, the
    #: network's, the multi-rate filter's)
    native_keys: frozenset[str] = frozenset()
    #: the components whose interface is the native FMU's own (a linear form's, the
    #: multi-rate filter's); the others keep the pythonfmu FMU's variables
    replaced: frozenset[str] = frozenset()


def native_system(system: SystemDescription, fmus: Mapping[str, Path], out_dir: Path | str,
                  kinds: tuple[str, ...] = NATIVE_KINDS,
                  platforms: Sequence[str] | None = None) -> NativeSystem:
    """Build native FMUs for the components of ``kinds`` and the system that uses them, and
    for the guidance interface's FMUs among ``fmus`` (beside the system, not in it).

    Parameters
    ----------
    system : SystemDescription
        The pythonfmu system.
    fmus : Mapping[str, Path]
        Its built pythonfmu FMUs (FMU key -> path).
    out_dir : Path or str
        Where the native FMUs go.
    kinds : tuple[str, ...], optional
        The FMU kinds to replace (default: every one that has a native FMU).
    platforms : Sequence[str] or None, optional
        The platforms the native FMUs carry binaries for (:func:`compile_fmu`); default
        the host's (what a run needs).

    Returns
    -------
    NativeSystem
        The system with native components; the other components as they were.

    Raises
    ------
    NativeBuildError
        If two components of one kind have forms of different shapes (named).
    """
    forms: dict[str, NativeForm] = {}
    filters: dict[str, tuple[tuple[ArraySpec, ...], dict[str, float]]] = {}
    built: dict[str, Path] = {}
    for kind in dict.fromkeys(c.fmu for c in system.components
                              if c.fmu in kinds and c.fmu in LINEAR_KINDS):
        mine = [c for c in system.components if c.fmu == kind]
        try:
            forms.update({c.name: form_of(c.fmu, Path(fmus[c.fmu]), c.parameters)
                          for c in mine})
        except NotImplementedError:         # not linear in this system (navigation sensors)
            if kind in ("estimator", "vehicle_estimator"):  # a Kalman filter in C of its own
                from .native_filters import filter_components
                built[kind], more = filter_components(kind, mine, fmus[kind], out_dir,
                                                      system.T, platforms)
                filters.update(more)
            continue                        # else its pythonfmu FMU stays
    # a static law works at any step; its h is the system's, for the default experiment
    forms = {k: dataclasses.replace(f, h=system.h) if f.static else f for k, f in forms.items()}
    base: dict[str, NativeForm] = {}
    for c in system.components:
        if c.name in forms:
            base.setdefault(c.fmu, forms[c.name])
    problems = [f"{c.name}: its {c.fmu} form does not have the shape of "
                f"{next(d.name for d in system.components if d.fmu == c.fmu)}'s"
                for c in system.components if c.name in forms
                and _shape(forms[c.name]) != _shape(base[c.fmu])]
    if problems:
        raise NativeBuildError("; ".join(problems))
    built.update({k: build_native_fmu(f, native_model(k), out_dir, system.T, system.h,
                                      platforms) for k, f in base.items()})
    # the guidance interface beside the system (REMUS 100 scenarios) or in it (vehicles
    # flown through it): its C models, the same variables, so components keep their
    # interface and parameters
    from .native_guidance import native_guidance_fmu
    built.update({k: native_guidance_fmu(k, fmus[k], out_dir, platforms) for k in GUIDANCE_KINDS
                  if k in fmus and k in kinds})
    if "network" in fmus and "network" in kinds:
        # the acoustic inbox's C model, the same variables: every network component keeps
        # its interface and parameters (the queue is sized for all of them)
        from .native_network import native_network_fmu
        built["network"] = native_network_fmu(
            fmus["network"], out_dir,
            [c.parameters for c in system.components if c.fmu == "network"], platforms)
    comps = tuple(dataclasses.replace(c, interface=tuple(native_specs(forms[c.name])),
                                      parameters=native_parameters(forms[c.name], base[c.fmu]))
                  if c.name in forms else
                  dataclasses.replace(c, interface=filters[c.name][0],
                                      parameters=filters[c.name][1])
                  if c.name in filters else c for c in system.components)
    # the nonlinear REMUS 100: its C model, the same variables; vehicles that differ in a
    # parameter fixed at export keep their pythonfmu FMU
    from .native_remus import REMUS_KINDS, VehiclesDiffer, native_remus_components
    remus = [k for k in REMUS_KINDS if k in kinds and any(c.fmu == k for c in comps)]
    for k in remus:
        try:
            built[k] = native_remus_components(k, fmus[k], comps, out_dir, platforms)
        except VehiclesDiffer:
            continue
    # a connection that carries data only for some value of a replaced component's
    # parameter (the truth in mode "ideal"): the native form has that value built in
    conns = tuple(dataclasses.replace(c, when=None) if c.when and c.when[0] in
                  (*forms, *filters)
                  and system.active(c) else c for c in system.connections)
    paths = {k: Path(v) for k, v in fmus.items()}
    paths.update(built)
    return NativeSystem(system=dataclasses.replace(system, components=comps, connections=conns),
                        fmus=paths, forms=forms, native_keys=frozenset(built),
                        replaced=frozenset((*forms, *filters)))


def _shape(f: NativeForm) -> tuple[Any, ...]:
    # the noise streams are built in, but for the key of a single keyed one (a parameter)
    streams = tuple((None if f.stream is not None else k, c) for k, c in f.noise_streams)
    return (f.nq, f.nu, f.ny, f.nxi, f.stream is not None, streams,
            tuple((r.key, r.name, r.value.shape) for r in f.roles))
