"""Navigation sensors as a REMUS 100 carries them: acoustic position fixes (USBL/LBL) every
few seconds, a Doppler velocity log (DVL, bottom track) at a few hertz, a depth sensor at
10 Hz, each with its noise and its dropouts (docs/remus100-6dof.md).

Sensor j reports at the steps k with k mod n_j = 0, n_j = period_j / h (a whole number),
unless its report is lost (probability ``dropout_j``, independently per report):

    fix[k]   = p[k] + sigma_fix n_f        (NED position, m; USBL/LBL)
    dvl[k]   = v[k] + sigma_dvl n_v        (NED velocity over ground, m/s: bottom track
                                            rotated by the vehicle's attitude)
    depth[k] = p_d[k] + sigma_depth n_d    (m)

and ``valid[k]`` = [fix, dvl, depth] is 1 for a new measurement, else 0 (the output then
holds the last one). Every step draws 7 standard normals and 3 uniforms from the generator
seeded [seed, 3_000_000 + vehicle], whether a sensor reports or not, so that the draws of
one sensor never shift another's; the vehicle's process and position-sensor noise streams
are untouched. The sigmas are standard deviations per sample (not intensities).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from .linalg_checks import ModelError

__all__ = ["MAX_SENSOR_CYCLE_STEPS", "NAV_SIZE", "NavigationSensors", "SensorStream",
           "SENSOR_STREAM_KEY", "SensedVehicle", "nav_output_spec", "sensor_parameter_specs",
           "sensors_from_parameters"]

#: the output vector [fix (3), dvl (3), depth, valid (3)]
NAV_SIZE = 10
#: the sensors' generator key offset: [seed, SENSOR_STREAM_KEY + vehicle]
SENSOR_STREAM_KEY = 3_000_000
#: the longest cycle (steps h) of a schedule without dropouts, lcm of the sensors' periods:
#: the navigation filter computes its periodic gain at every step of the cycle
#: (estimator_fmu.multirate.periodic_filter), and the prediction a loop per step
MAX_SENSOR_CYCLE_STEPS = 10_000


@dataclass(frozen=True)
class NavigationSensors:
    """Periods (s), standard deviations and dropout probabilities of the three sensors.
    Defaults: REMUS 100 class (a USBL fix every 2 s with 1 m per axis, a 1200 kHz DVL at
    5 Hz with 1 cm/s, a pressure sensor at 10 Hz with 5 cm)."""

    fix_period: float = 2.0
    fix_sigma: float = 1.0
    fix_dropout: float = 0.1
    dvl_period: float = 0.2
    dvl_sigma: float = 0.01
    dvl_dropout: float = 0.02
    depth_period: float = 0.1
    depth_sigma: float = 0.05
    depth_dropout: float = 0.0
    #: m/s per axis: the largest ocean current the navigation filter believes
    #: (estimator_fmu.multirate); not a sensor, but the table configures the filter too
    current_max: float = 1.0

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ModelError(f"[sensors] {f.name} = {v!r} is not a finite number")
            if f.name.endswith("dropout"):
                if not 0.0 <= v < 1.0:
                    raise ModelError(f"[sensors] {f.name} = {v:g} must be in [0, 1)")
            elif v <= 0.0:
                raise ModelError(f"[sensors] {f.name} = {v:g} must be positive")

    @classmethod
    def from_mapping(cls, table: dict[str, Any]) -> NavigationSensors:
        """From a [sensors] table (its keys but ``kind``), naming an unknown key."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(table) - known - {"kind"})
        if unknown:
            raise ModelError(f"[sensors] unknown key(s) {', '.join(unknown)}; accepted: kind, "
                             f"{', '.join(sorted(known))}")
        return cls(**{k: v for k, v in table.items() if k != "kind"})

    def to_mapping(self) -> dict[str, float]:
        """The fields as a plain dict."""
        return {k: float(v) for k, v in asdict(self).items()}

    def steps(self, h: float) -> np.ndarray:
        """[n_fix, n_dvl, n_depth]: each period in steps of h.

        Raises
        ------
        ModelError
            Naming the period that is not a whole number of steps.
        """
        out = []
        for name in ("fix_period", "dvl_period", "depth_period"):
            period = getattr(self, name)
            n = round(period / h)
            if n < 1 or abs(n * h - period) > 1e-9 * period:
                raise ModelError(f"[sensors] {name} = {period:g} s is not a whole number of "
                                 f"steps h = {h:g} s")
            out.append(n)
        cycle = math.lcm(*out)
        if self.lossless and cycle > MAX_SENSOR_CYCLE_STEPS:
            periods = [f"{name} = {getattr(self, name):g} s" for name in
                       ("fix_period", "dvl_period", "depth_period")]
            raise ModelError(f"[sensors] {', '.join(periods)} report together every {cycle} "
                             f"steps of h = {h:g} s ({cycle * h:g} s), more than the "
                             f"{MAX_SENSOR_CYCLE_STEPS} steps the navigation filter's cycle may "
                             "take without dropouts (a gain per step of it); choose periods "
                             "with a shorter common multiple")
        return np.array(out, dtype=np.int64)

    @property
    def dropouts(self) -> np.ndarray:
        """The dropout probabilities [fix, dvl, depth]."""
        return np.array([self.fix_dropout, self.dvl_dropout, self.depth_dropout])

    @property
    def lossless(self) -> bool:
        """No report is ever lost: the schedule is periodic."""
        return not self.dropouts.any()

    @property
    def sigmas(self) -> np.ndarray:
        """Standard deviation of each of the 7 measured values [fix (3), dvl (3), depth]."""
        return np.array([self.fix_sigma] * 3 + [self.dvl_sigma] * 3 + [self.depth_sigma])


class SensorStream:
    """The sensors of one vehicle sampled at h: ``measure(k, p, v)`` writes the vector
    [fix, dvl, depth, valid] of sample k into ``out`` (module docstring)."""

    BLOCK = 1024

    def __init__(self, sensors: NavigationSensors, h: float, seed: int, vehicle: int):
        self.sensors, self.h = sensors, float(h)
        self.period = sensors.steps(self.h)
        self._sigma = sensors.sigmas
        self._drop = sensors.dropouts
        self.seed, self.vehicle = int(seed), int(vehicle)
        self._rng = np.random.default_rng([self.seed, SENSOR_STREAM_KEY + self.vehicle])
        self._normal = np.empty((0, 7))
        self._uniform = np.empty((0, 3))
        self._i = 0
        self.out = np.zeros(NAV_SIZE)

    def _next(self) -> tuple[np.ndarray, np.ndarray]:
        if self._i == len(self._normal):
            self._normal = self._rng.standard_normal((self.BLOCK, 7))
            self._uniform = self._rng.random((self.BLOCK, 3))
            self._i = 0
        i = self._i
        self._i += 1
        return self._normal[i], self._uniform[i]

    def measure(self, k: int, p: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The outputs of sample k for the NED position p (m) and velocity v (m/s)."""
        n, r = self._next()
        o = self.out
        due = (k % self.period == 0) & (r >= self._drop)
        o[7:10] = due
        if due[0]:
            o[0:3] = p + self._sigma[0:3] * n[0:3]
        if due[1]:
            o[3:6] = v + self._sigma[3:6] * n[3:6]
        if due[2]:
            o[6] = p[2] + self._sigma[6] * n[6]
        return o

    def get_state(self) -> dict:
        """The generator, the current block and position, the held outputs (copies)."""
        return {"rng": self._rng.bit_generator.state, "normal": self._normal.copy(),
                "uniform": self._uniform.copy(), "i": self._i, "out": self.out.copy()}

    def set_state(self, state: dict) -> None:
        """Restore :meth:`get_state` (validated first)."""
        normal = np.array(state["normal"], dtype=float).reshape(-1, 7)
        uniform = np.array(state["uniform"], dtype=float).reshape(-1, 3)
        out = np.array(state["out"], dtype=float)
        i = int(state["i"])
        if len(normal) != len(uniform) or not 0 <= i <= len(normal) or out.shape != (NAV_SIZE,):
            raise ValueError("the sensor state does not fit this vehicle's sensors")
        self._rng.bit_generator.state = state["rng"]
        self._normal, self._uniform, self._i, self.out = normal, uniform, i, out


_UNITS = {"period": "s", "dropout": None}
_SIGMA_UNITS = {"fix": "m", "dvl": "m/s", "depth": "m"}


def sensor_parameter_specs(config: dict[str, Any]) -> list[Any]:
    """FMU parameters ``sensors.<field>`` for every field of the build configuration's
    ``sensors`` table; none without one."""
    from fmu_common.interface import ArraySpec

    table = config.get("sensors")
    if not table:
        return []
    sensors = NavigationSensors.from_mapping(table)
    specs = []
    for f in fields(NavigationSensors):
        sensor, what = f.name.split("_")
        if f.name == "current_max":
            unit, doc = "m/s", "the largest ocean current the filter believes, per axis"
        else:
            unit = _SIGMA_UNITS[sensor] if what == "sigma" else _UNITS[what]
            doc = sensor + ": " + {"period": "time between reports", "sigma": "standard "
                                   "deviation per report and axis", "dropout": "probability "
                                   "that a report is lost"}[what]
        specs.append(ArraySpec(f"sensors.{f.name}", (), "parameter", doc,
                               start=float(getattr(sensors, f.name)), unit=unit))
    return specs


def nav_output_spec(config: dict[str, Any]) -> list[Any]:
    """The vehicle FMUs' output ``nav`` (10) when the configuration has sensors, else none."""
    from fmu_common.interface import ArraySpec

    if not config.get("sensors"):
        return []
    return [ArraySpec("nav", (NAV_SIZE,), "output", "navigation sensors: acoustic fix (NED, m), "
                      "DVL velocity over ground (NED, m/s), depth (m), and valid flags [fix, "
                      "dvl, depth] (1: a new report this sample)")]


def sensors_from_parameters(par: dict[str, Any]) -> NavigationSensors:
    """The :class:`NavigationSensors` of an FMU's ``sensors.<field>`` parameters (the
    fields absent from ``par`` keep their defaults)."""
    return NavigationSensors(**{f.name: float(par[f"sensors.{f.name}"])
                                for f in fields(NavigationSensors)
                                if f"sensors.{f.name}" in par})


class SensedVehicle:
    """A linear vehicle (a :class:`plant_model.plant.Plant` of one vehicle, x = [p; v])
    with navigation sensors on its true state, written into ``nav_out`` (10 floats) at
    every sample. ``s`` is the plant's state; ``step``, ``get_state``, ``set_state`` as the
    plant's."""

    def __init__(self, plant: Any, sensors: NavigationSensors, nav_out: np.ndarray):
        self.plant, self.nav_out = plant, nav_out
        self._stream = SensorStream(sensors, plant.model.h, plant.seed,
                                    int(plant.model.noise_keys[0]))
        self._measure()

    @property
    def s(self) -> np.ndarray:
        """The plant's sampled state [x; w]."""
        return self.plant.s

    def _measure(self) -> None:
        x = self.plant.s
        self.nav_out[:] = self._stream.measure(self.plant.k, x[0:3], x[3:6])

    def step(self, u: np.ndarray) -> None:
        """The plant's step, then the sensors of the new sample."""
        self.plant.step(u)
        self._measure()

    def get_state(self) -> dict:
        """The plant's and the sensors' state."""
        return {"plant": self.plant.get_state(), "nav": self._stream.get_state()}

    def set_state(self, state: dict) -> None:
        """Restore :meth:`get_state` (the plant validates first)."""
        self.plant.set_state(state["plant"])
        self._stream.set_state(state["nav"])
        self.nav_out[:] = self._stream.out
