"""The registry of deployments and the one branch on it: :func:`make_setup` makes the
:class:`~orchestrator.running.setup.RunSetup` of a scenario; :func:`scenario_system` and
:func:`build` are its system and FMUs for the scenario's own method."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..cosim.system import SystemDescription
from ..scenario import Scenario, ScenarioError
from ..scenario.size import memory_short
from .memory import check_design
from .per_vehicle import PerVehicleSetup
from .setup import Method, RunSetup, check_setup
from .stacked import StackedSetup

__all__ = ["DEPLOYMENT_SETUPS", "build", "check_memory", "check_native", "check_run",
           "check_size", "make_setup", "scenario_system"]

#: the setup of each deployment ([simulation] deployment)
DEPLOYMENT_SETUPS: dict[str, type[RunSetup]] = {"stacked": StackedSetup,
                                                "per-vehicle": PerVehicleSetup}


def make_setup(sc: Scenario, fmu_dir: Path | str, methods: Sequence[Method] = (), *,
               coupling: str = "gauss-seidel", predict: str = "stationary",
               master: str = "auto") -> RunSetup:
    """The setup of a scenario: the one place that branches on the deployment.

    Parameters
    ----------
    sc : Scenario
    fmu_dir : Path or str
        Where its FMUs go.
    methods : sequence of Method, optional
        The methods that will run (default: the scenario's own).
    coupling : str, optional
        The master's coupling.
    predict : str, optional
        One of :data:`PREDICT_LEVELS`.
    master : str, optional
        auto, native or python (:func:`orchestrator.cosim.master.run_system`).

    Returns
    -------
    RunSetup

    Raises
    ------
    ScenarioError
        If the combination cannot run (:func:`check_setup`).
    ModelError
        If the stacked design (stacked deployment, centralized per-vehicle methods) is
        estimated too long or too large (:func:`check_size`).
    """
    check_setup(sc, coupling)
    setup = DEPLOYMENT_SETUPS[sc.deployment](sc, fmu_dir, methods, coupling=coupling,
                                             predict=predict)
    setup.master = master
    return setup


def check_size(sc: Scenario, methods: Sequence[Method] = (), predict: str = "stationary"
               ) -> None:
    """Refuse, before anything is built, a scenario whose stacked design (the stacked
    deployment, or a centralized per-vehicle method) is estimated too long or too large:
    what :func:`make_setup` checks, without making the setup (a campaign's points).

    Parameters
    ----------
    sc : Scenario
    methods : sequence of Method, optional
        The methods that will run (default: the scenario's own).
    predict : str, optional
        The prediction level.

    Raises
    ------
    ModelError
        One line with the vehicles, the states, the estimate and the limit.
    """
    methods = tuple(methods) or (Method.of(sc),)
    if sc.deployment == "stacked":
        check_design(sc, [m.estimator for m in methods], predict)
        return
    central = [m.estimator for m in methods if m.architecture == "centralized"]
    if central:
        check_design(sc, central, predict, "centralized")


def scenario_system(sc: Scenario) -> SystemDescription:
    """The system description of a scenario with its run settings (seed, estimator mode,
    tracking law, architecture, FMU kind): what the master runs and the exports write.

    Parameters
    ----------
    sc : Scenario
        A validated scenario.

    Returns
    -------
    SystemDescription
        The paper's loop of plant, estimator and controller, named after the scenario; for
        ``deployment = "per-vehicle"`` the leader and one vehicle, estimator and controller
        per AUV (:mod:`orchestrator.cosim.per_vehicle`) in the scenario's architecture.
    """
    return make_setup(sc, Path(".")).python_system(Method.of(sc), sc.seed)


def build(sc: Scenario, out_dir: Path | str) -> dict[str, Path]:
    """The pythonfmu FMUs of a scenario (its deployment and architecture) in ``out_dir``
    (taken from the FMU cache when an identical build exists).

    Parameters
    ----------
    sc : Scenario
        The scenario; its values are the FMUs' start values.
    out_dir : Path or str
        Folder for the ``.fmu`` files.

    Returns
    -------
    dict
        FMU key (plant, estimator, controller; or leader, vehicle, ...) -> path; for
        REMUS 100 vehicles also 'guidance' and 'autopilot' (AuvGuidance, AuvAutopilot:
        standalone, for a host's own vehicle; :func:`.fmus.guidance_configs`).
    """
    from ..cosim.build import build_fmus
    from .fmus import guidance_configs
    paths = dict(make_setup(sc, Path(out_dir)).python_fmus(Method.of(sc)))
    extra = guidance_configs(sc)
    if extra:
        paths.update(build_fmus(None, Path(out_dir), kinds=extra))
    return paths


def check_run(sc: Scenario, methods: Sequence[Method] = (), *,
              coupling: str = "gauss-seidel", predict: str = "stationary",
              available: int | None = None, setup: RunSetup | None = None,
              record_hz: float | None = None,
              record: Sequence[str] | None = None) -> int:
    """Every check a run makes before it starts: the one set of rules of ``run``,
    ``compare``, each ``envelope`` point and each ``campaign`` point.

    The scenario's bounds (h > 0, T at least one whole step, the step samples the model,
    the run settings' values) are the loader's, checked when a scenario is made
    (:func:`orchestrator.scenario.load_scenario`, :meth:`Scenario.with_run`,
    :func:`orchestrator.scenario.scenario_from_dict`); this function checks what only the
    run decides, in this order, each refusal one line naming the problem:

    1. the combination of deployment, links, sensors, vehicles and coupling
       (:func:`orchestrator.running.setup.check_setup`);
    2. the stacked design's estimated time and memory (:func:`check_size`);
    3. native FMUs need a C compiler (:func:`check_native`);
    4. the groups of outputs recorded (``--record``) are the layout's and the run has
       them (:func:`check_record`);
    5. a chunk of the run fits in memory and its recording on the disk
       (:func:`check_memory`): a T that would not finish (``T = 1e9``: 1e11 steps) is
       refused here, at once.

    Parameters
    ----------
    sc : Scenario
        A validated scenario.
    methods : sequence of Method, optional
        The methods that will run (default: the scenario's own).
    coupling : str, optional
        The master's coupling.
    predict : str, optional
        The prediction level (``--predict``).
    available : int, optional
        Bytes of memory available (default
        :func:`orchestrator.scenario.size.available_memory`).
    setup : RunSetup, optional
        The run's own setup (:func:`make_setup` of the same scenario and methods): the
        system it builds for the memory check is then the one the run uses (a fleet's
        vehicle laws and network loop are made once, not twice).
    record_hz : float, optional
        The recording's samples per second (the disk the .rrd needs).
    record : sequence of str, optional
        The groups of outputs recorded (None: all; :mod:`orchestrator.recording.selection`).

    Returns
    -------
    int
        The estimated bytes of the traces.

    Raises
    ------
    ScenarioError
        A combination that cannot run, traces that would not fit.
    ModelError
        A stacked design estimated too long or too large.
    NativeBuildError
        Native FMUs and no C compiler.
    """
    methods = tuple(methods) or (Method.of(sc),)
    if setup is None:
        setup = make_setup(sc, Path("."), methods, coupling=coupling, predict=predict)  # 1, 2
    check_native(sc)
    system = setup.python_system(Method.of(sc), sc.seed)                # as scenario_system
    share = check_record(sc, system, record)
    return check_memory(sc, len(methods), available, width=system.output_width(),
                        record_hz=record_hz, record_share=share)


def check_record(sc: Scenario, system: SystemDescription,
                 record: Sequence[str] | None) -> float:
    """Check the groups of outputs a run records (``--record``): each a group of the
    scenario's layout (:mod:`orchestrator.recording.selection`: the fleet's when it has one)
    and, for the groups only some runs have (links, actuators, set-points), one this run
    has.

    Parameters
    ----------
    sc : Scenario
    system : SystemDescription
        The run's system (its components and outputs).
    record : sequence of str or None
        The groups (None: all).

    Returns
    -------
    float
        The share of the run's recorded values the groups hold (1 for all), from the
        columns of the stacked layout's keys (for the disk estimate).

    Raises
    ------
    ScenarioError
        One line naming the group and the layout's groups, or what the run lacks.
    """
    from ..recording.selection import Selection
    from .fmus import fleet_layout
    fleet = fleet_layout(sc) is not None
    try:
        selection = Selection.of(fleet, record)
    except ValueError as exc:
        raise ScenarioError(f"--{exc}") from None
    if selection.groups is None:
        return 1.0
    names = system.trace_names()
    lacking = {"links": ("acoustic links", any(c.fmu == "network" for c in system.components)),
               "actuators": ("nonlinear vehicles", ("vehicle_1", "rpm") in names),
               "setpoint": ("guidance FMUs", ("guidance_1", "speed") in names)}
    absent = {g: what for g, (what, present) in lacking.items() if fleet and not present}
    for group in selection.names():
        if group in absent:
            has = [g for g in Selection.of(fleet, None).names() if g not in absent]
            raise ScenarioError(f"--record {group}: this run has no {absent[group]}, so no "
                                f"{group} to record (its groups: {', '.join(has)})")
    s = sc.system
    width = {"x": s.n, "xhat": s.n, "u": s.m, "e": s.p, "w": s.r, "what": s.r, "z": s.l,
             "zhat": s.l, "y": s.p, "ybar": s.l}
    every = sum(width.get(k, 0) for k in Selection.of(fleet, None).keys())
    return sum(width.get(k, 0) for k in selection.keys()) / max(every, 1)


def check_native(sc: Scenario) -> None:
    """Native FMUs (``[simulation] fmus = "native"``, ``--fmus native``) need a C compiler.

    Raises
    ------
    NativeBuildError
        ``--fmus native: no C compiler: ...`` (one line saying what to install).
    """
    if sc.fmus == "native":
        from ..cosim.native import NativeBuildError, compiler
        try:
            compiler()
        except NativeBuildError as exc:
            raise NativeBuildError(f"--fmus native: {exc}") from None



#: bytes per recorded value in a .rrd (the value, its share of the time columns and the
#: chunk framing: measured 26 for the paper's 20 series at every step, 18-30 for fleets)
RRD_BYTES_PER_VALUE = 32


def check_memory(sc: Scenario, n_methods: int, available: int | None = None, *,
                 width: int | None = None, record_hz: float | None = None,
                 disk: int | None = None, record_share: float = 1.0) -> int:
    """Refuse a run whose chunks cannot fit in memory, or whose recording cannot fit on the
    disk, before anything is built.

    A run keeps what it is asked to keep, not its horizon: the master's trace buffers hold
    one chunk of steps (:func:`orchestrator.running.statistics.chunk_steps`: at most 64
    MiB), and so do the chunk's copies (the stacked layout, the one sent to the .rrd writer,
    the writer's gathered rows): bytes = 8 x 4 x chunk x width, whatever T. The statistics
    are sums; the .rrd is written as the run goes. What grows with T is the file: about
    :data:`RRD_BYTES_PER_VALUE` bytes per recorded value (every ``stride``-th step of the
    first seed of each method), checked against the disk's free space.

    Parameters
    ----------
    sc : Scenario
        The scenario (its T, h and system).
    n_methods : int
        Methods simulated (estimator modes x tracking laws).
    available : int, optional
        Bytes of memory available (default :func:`available_memory`).
    width : int, optional
        Values per step (default: those of the scenario's own system,
        :func:`scenario_system`).
    record_hz : float, optional
        The recording's samples per second (:func:`orchestrator.running.fmus.record_stride`).
    disk : int, optional
        Bytes free on the disk of the output (default: that of the current folder).
    record_share : float, optional
        The share of the values recorded (``--record``: :func:`check_record`).

    Returns
    -------
    int
        The estimated bytes of memory (a chunk and its copies).

    Raises
    ------
    ScenarioError
        Naming T, h, the number of steps and both sizes, if the chunks exceed MEMORY_SHARE
        of the memory available or the recording the free disk.
    """
    import shutil

    from .fmus import record_stride
    from .statistics import chunk_steps
    width = scenario_system(sc).output_width() if width is None else width
    chunk = min(chunk_steps(width), sc.steps)
    need = 8 * 4 * chunk * width
    short = memory_short(need, available)
    if short is not None:
        raise ScenarioError(
            f"a chunk of {chunk} steps ({width} values per step) needs about "
            f"{need / 1e9:.3g} GB, more than the {short / 1e9:.3g} GB of memory available")
    samples = sc.steps // record_stride(sc, record_hz) + 1
    rrd = RRD_BYTES_PER_VALUE * samples * width * n_methods * record_share
    free = shutil.disk_usage(".").free if disk is None else disk
    if rrd > free:
        raise ScenarioError(
            f"T = {sc.T:g} s with h = {sc.h:g} s is {sc.steps:.4g} steps: its recording "
            f"({width} values per sample, {n_methods} method(s), {samples:.4g} samples) "
            f"needs about {rrd / 1e9:.3g} GB on disk, more than the {free / 1e9:.3g} GB "
            "free; shorten T, lengthen h, record fewer samples (--record-hz) or fewer "
            "outputs (--record)")
    return need
