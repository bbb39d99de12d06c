"""The scenario-to-FMU mapping: the FMUs' configuration, the variable tables of
``fmus/README.md`` and the recording's layout (the system a scenario runs and the FMUs it is
built into: :func:`orchestrator.running.systems.scenario_system`, :func:`~.systems.build`)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cosim.build import GUIDANCE_KINDS, build_fmus, fmu_config, variables_markdown
from ..scenario import Scenario

if TYPE_CHECKING:
    from ..recording import FleetLayout

__all__ = ["FMU_README_HEAD", "GUIDANCE_README_HEAD", "scenario_config", "build_fmus",
           "fmu_readme", "guidance_configs", "write_fmu_readme", "fleet_layout", "record_stride"]

FMU_README_HEAD = """# FMUs

`auv-cosim build` writes a scenario's three FMI 2.0 co-simulation FMUs, with this file
for that scenario, into `out/<scenario>_fmus/` (or `--out`; the `.fmu` files are not
committed: build them). They are built with pythonfmu for one scenario: its
dimensions fix the number of variables, its values are the start values. Whatever a host
sets in initialization mode is used: the plant discretizes, the estimator designs its
filters and the controller solves its Riccati and Sylvester equations in
exitInitializationMode.

Importing them needs a Python interpreter in the host process: pythonfmu's binary embeds
the host's Python (fmpy and libcosimpy run the FMU in their own interpreter; a non-Python
host must load libpython, see docs/other-tools.md), so each FMU declares
`needsExecutionTool="true"`. What each FMU's code imports from that Python:

| FMU | needs |
|---|---|
| `AuvPlant` | Python 3.11+, numpy, scipy (matrix exponential, Van Loan); networkx for fleet FMUs |
| `AuvEstimator` | Python 3.11+, numpy, scipy (discrete Riccati equation); networkx for fleet FMUs |
| `AuvController` | Python 3.11+, numpy, scipy (Riccati, Sylvester); networkx for fleet FMUs |
| `AuvNetwork` (per-vehicle fleets over acoustic links, docs/network.md) | Python 3.11+, numpy |
| `AuvRemus6dof` (nonlinear REMUS 100) | Python 3.11+, numpy, scipy; numba if present |
| `AuvRemus6dofActuated` (the same, commands in) | Python 3.11+, numpy, scipy; numba if present |

pythonfmu itself and this project's modules travel inside each FMU (`resources/`).
All three support fmi2Get/SetFMUstate and fmi2Serialize/DeSerializeFMUstate.

Fleet FMUs do not expose the stacked matrices (they grow as (N p)^2) but the quantities
a user changes: `vehicle[i].mass`, `vehicle[i].added_mass[k]`, `vehicle[i].offset[k]`,
`vehicle[i].x0[k]`, `vehicle[i].current.time_constant`, `vehicle[i].current.sigma`,
`vehicle[i].W_x`, `vehicle[i].V_y`, `vehicle[i].Q`, `vehicle[i].R`, `a[i,j]` (weight of the
edge j -> i, only for edges that exist), `a0[i]` (pinning), `coupling[a,b]`, `leader.F`,
`leader.H`, `leader.z0`, `leader.W_z`; each FMU exposes only what its mathematics reads.
The controller's String parameter `tracking` chooses `lq` (the paper) or `regulator`.

Conventions: FMI structured names (`A[1,2]` is row 1, column 2), SI units where a
quantity has one (the paper's example is dimensionless apart from time), every variable
has a description. Outputs with direct feedthrough declare it in ModelStructure: the
estimator's estimates depend on y, ybar (and the truth inputs, read only in mode `ideal`),
the controller's u on the estimates; the plant's outputs depend on no input.

Errors: a design that cannot exist or a bad parameter makes exitInitializationMode fail
(pythonfmu reports every Python exception as fmi2Fatal) with a logged message naming the
problem; a NaN or infinite input is logged when set and the next fmi2DoStep returns
fmi2Discard, naming the input. Plant and estimator accept only the communication step
`h` they were set up for (`canHandleVariableCommunicationStepSize="false"`).

The per-vehicle deployment (`auv-cosim build --deployment per-vehicle`) builds other FMUs
instead: `AuvLeader`, `AuvVehicle`, `AuvVehicleEstimator` and `AuvVehicleController`
(distributed) or `AuvCentralController` (centralized), one per kind for every vehicle;
`docs/per-vehicle.md` lists their variables and wiring. A vehicle of model
`remus100-6dof` is an `AuvRemus6dof` in place of `AuvVehicle`: the same input `u` and
outputs `y`, `x`, `w`, plus `attitude`, `rpm`, `rudder`, `stern` and `saturated`; with
`[sensors] kind = "remus"` both vehicle FMUs also output `nav` (acoustic fix, DVL, depth,
valid flags), which the estimator reads in place of `y`. A vehicle of model
`remus100-6dof-guided` is three FMUs: `AuvGuidance` -> `AuvAutopilot` ->
`AuvRemus6dofActuated` (inputs `rpm_command`, `rudder_command`, `stern_command`; the
outputs of `AuvRemus6dof` plus `velocity`, `rates`, `depth`; docs/guidance.md).

Native FMUs, no Python needed (`auv-cosim export native`, docs/native.md): once designed,
every FMU but `AuvNetwork`, `AuvRemus6dof` and the guidance interface (`AuvGuidance`,
`AuvAutopilot`, below) is a linear system, y = C q + D u + c + G xi and
q+ = A q + B u + Bo y + b + F xi. The export compiles it from C99 (the shared FMI
plumbing `fmu_core.c` and the linear system `linear_fmu.c`)
(`AuvControllerNative`, `AuvEstimatorNative`, `AuvPlantNative`, and per vehicle
`AuvLeaderNative`, `AuvVehicleNative`, `AuvVehicleEstimatorNative`,
`AuvVehicleControllerNative`, `AuvCentralControllerNative`), with the same inputs, outputs
and direct-feedthrough declarations, `needsExecutionTool="false"`, the sources in
`sources/` and a `binaries/linux64` library that needs only libc and libm. Its parameters
are the designed matrices (`Ks`, `Ce`, `Dm`, `Aq`, `Bu`, `Ad`, `Bd`, `Lq`, `Lr`, ...), not
the model: a native FMU does not solve the Riccati equations again, so a design change
means exporting again or setting those parameters. The native plant draws numpy's
normals in C (PCG64 and numpy's ziggurat, seeded from `seed`, and a vehicle's `stream`,
like numpy's SeedSequence), so native and pythonfmu runs of a seed agree. A bad parameter
gives fmi2Error with a logged message naming the variable; state get/set/serialize are
supported.

Below: the variables for the built-in `{scenario}` scenario (generated by `auv-cosim build`).

"""


GUIDANCE_README_HEAD = """## The guidance interface: `AuvGuidance` and `AuvAutopilot`

For a host that flies its own vehicle (docs/guidance.md, examples in docs/examples/):
`AuvGuidance` turns the controller's NED force `u` (N) into the set-points a vehicle stack
takes, speed through the water, course and depth with their rates, through the design
model's reference velocity v_ref' = (u - D v_ref)/M per NED axis; `AuvAutopilot` turns
those set-points and the vehicle's measured velocity through the water (body axes),
attitude, body rates and depth into rpm, rudder and stern-plane commands, clipped to the
limits `n_max` and `delta_max`, with anti-windup. Both need Python 3.11+ and numpy.
`auv-cosim build` and `export osp|ssp` ship them for scenarios of REMUS 100 vehicles,
vehicle 1's design model and start as their start values; `export native` ships them as
native (C) FMUs with the same variables, `AuvGuidanceNative` and `AuvAutopilotNative`, which
need no Python. They stand beside the system (no wiring): a host connects them. Any
communication step. A NaN input is refused at the next fmi2DoStep (fmi2Discard, message
logged); a non-positive `M[i]` or `D[i]` fails initialization naming it. The tables below
carry the defaults: the design model of `remus100-6dof`.

"""


def scenario_config(sc: Scenario) -> dict[str, Any]:
    """The FMU configuration of a scenario: dimensions, start values, h, T, seed, mode.

    Parameters
    ----------
    sc : Scenario
        A validated scenario with its run settings.

    Returns
    -------
    dict
        JSON-ready configuration the three FMUs are built with
        (:func:`orchestrator.cosim.build.fmu_config`); with a [design] force limit the
        controller's ``u_max``, every vehicle's axes in the stacked input order.
    """
    cfg = fmu_config(sc.system.to_mapping(), sc.system.dims, sc.h, sc.T, sc.seed, sc.estimator,
                     sc.tracking, None if sc.fleet is None else sc.fleet.spec)
    if sc.estimator_P0 is not None:     # [estimator] P0 (one vehicle's in a fleet)
        cfg["P0"] = np.asarray(sc.estimator_P0, dtype=float).tolist()
    if sc.design is not None and sc.design.clip:
        cfg["u_max"] = [float(x) for row in sc.design.u_max for x in row]
    return cfg


def guidance_configs(sc: Scenario) -> dict[str, dict[str, Any]]:
    """The configurations of ``AuvGuidance`` and ``AuvAutopilot`` for a scenario whose
    vehicles are REMUS 100s (family ``remus100``, NED layout), else none: vehicle 1's
    design model (M, D per NED axis), its start (depth, velocity through the water
    x0[3:6] - w0, its course) and autopilot gains as start values (docs/guidance.md;
    :func:`orchestrator.cosim.guided.stack_configs`, which configures every vehicle's
    guidance FMUs of a ``remus100-6dof-guided`` fleet).

    Parameters
    ----------
    sc : Scenario

    Returns
    -------
    dict[str, dict[str, Any]]
        {} or {'guidance': config, 'autopilot': config} (keys of FMU_KINDS).
    """
    from plant_model.vehicle_models import find

    from ..cosim.guided import stack_configs
    if sc.fleet is None:
        return {}
    models = sc.fleet.models
    entries = [find(m.name) for m in models]
    if any(e is None or not e.guidance for e in entries):
        return {}
    return stack_configs(models[0], sc.fleet.views[0], sc.h, sc.T, sc.seed)


def fmu_readme(sc: Scenario) -> str:
    """The text of ``fmus/README.md``: what the FMUs need, every variable of the FMUs built
    for ``sc`` (name, causality, variability, unit, start, description), then those of
    ``AuvGuidance`` and ``AuvAutopilot`` (with the REMUS 100 design model's defaults when
    ``sc`` has no REMUS 100 vehicles).

    Parameters
    ----------
    sc : Scenario
        The scenario the variable tables are generated for.

    Returns
    -------
    str
        Markdown.
    """
    guidance = guidance_configs(sc) or {k: {"dims": {}, "h": sc.h, "T": sc.T}
                                        for k in GUIDANCE_KINDS}
    return (FMU_README_HEAD.format(scenario=sc.name) + variables_markdown(scenario_config(sc))
            + GUIDANCE_README_HEAD + variables_markdown({}, guidance))


def write_fmu_readme(sc: Scenario, path: Path) -> None:
    """Write :func:`fmu_readme` of ``sc`` to ``path`` (``fmus/README.md``).

    Parameters
    ----------
    sc : Scenario
        The scenario the variable tables are generated for.
    path : Path
        The file to write.
    """
    path.write_text(fmu_readme(sc))


def fleet_layout(sc: Scenario) -> FleetLayout | None:
    """The recording layout of a fleet scenario.

    Parameters
    ----------
    sc : Scenario

    Returns
    -------
    FleetLayout or None
        None for a single stacked system or a fleet whose vehicles have no NED positions.
    """
    from ..recording import FleetLayout
    if sc.fleet is None:
        return None
    info = sc.fleet.info(sc.system)
    if info.position_index is None:
        return None
    N = info.N

    def block(per: int) -> np.ndarray:
        return np.arange(N * per).reshape(N, per)

    return FleetLayout(
        position_index=info.position_index, error_index=block(info.s),
        control_index=block(info.q), error_names=info.output_names,
        control_names=info.input_names, leader_output=info.leader_output,
        offsets=info.offsets, edges=info.edges, pinned=info.pinned,
        state_index=block(info.p), state_names=info.state_names,
        disturbance_index=block(info.r), disturbance_names=info.disturbance_names,
        **_actuator_limits(sc.fleet.models[0].parameters),
    )


def _actuator_limits(parameters: dict) -> dict[str, float]:
    """The nonlinear vehicle's propeller (rpm) and fin (rad) limits the recording draws
    (vehicle 1's; none for a linear model)."""
    data = parameters.get("nonlinear") or {}
    return {k: float(data[k]) for k in ("n_max", "delta_max") if k in data}


def record_stride(sc: Scenario, record_hz: float | None = None) -> int:
    """Steps between recorded samples: every step for a single system; for a fleet about
    ``record_hz`` samples per second (default 20 Hz), which keeps .rrd files of large
    fleets to tens of megabytes (every step is still simulated and summarised).

    Parameters
    ----------
    sc : Scenario
    record_hz : float, optional
        Recorded samples per second, Hz.

    Returns
    -------
    int
        The stride, at least 1.
    """
    if record_hz is None:
        if sc.fleet is None:
            return 1
        record_hz = 20.0
    return max(1, int(round(1.0 / (record_hz * sc.h))))
