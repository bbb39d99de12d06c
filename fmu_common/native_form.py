"""A designed FMU as a discrete-time linear system: what a native (C) FMU computes.

Once its Riccati, Sylvester and Kalman equations are solved, every FMU of the project that
is not the acoustic network is linear: with inputs u, state q and standard normal noise xi
drawn once per step,

    y      = C q + D u + c + G xi           (outputs at t_k; D: direct feedthrough)
    y_j    = min(max(y_j, -s_j), s_j)       (the rows of the role ``sat``, if any: a
                                             controller's force limit u_max)
    q(k+1) = A q + B u + Bo y + b + F xi    (one step h)

A :class:`NativeForm` holds those matrices under the names the native FMU gives its
parameters (a :class:`Role` each: ``Ks``, ``Ce``, ``Ad``, ...), with the slave's own input
and output arrays, so the native FMU has the same interface as the pythonfmu one. Each
slave builds its form from the mathematics it set up (``native_form()``); the C source and
its build are fmu_common/native/linear_fmu.c (on the shared FMI plumbing fmu_core.c) and
orchestrator.cosim.native.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .interface import ArraySpec

__all__ = ["FMU_IMPLEMENTATIONS", "ROLE_KEYS", "BlockLayout", "NativeForm", "Role"]

#: how a component's FMU is implemented: the pythonfmu slave, or the compiled (C) form of
#: its linear mathematics where it has one (the others stay pythonfmu)
FMU_IMPLEMENTATIONS = ("python", "native")

#: the matrices of the equations above; B and D act on a range of u, F and G on one of xi,
#: G also writes into a range of y; sat (a vector of positive limits) clips a range of y
ROLE_KEYS = ("A", "B", "Bo", "b", "F", "C", "D", "c", "G", "q0", "sat")


@dataclass(frozen=True)
class Role:
    """One matrix of the equations, as the FMU parameter ``name``.

    ``sign`` -1 stores the matrix with the opposite sign (a gain K with u = -K x is the
    role D = -K under the parameter name K). ``col0`` is the first column of the vector it
    multiplies (u for B and D, xi for F and G), ``row0`` the first row it writes (G only).
    """

    key: str
    name: str
    value: np.ndarray
    description: str
    sign: float = 1.0
    col0: int = 0
    row0: int = 0
    unit: str | None = None

    def __post_init__(self) -> None:
        if self.key not in ROLE_KEYS:
            raise ValueError(f"role {self.key!r} is not one of {ROLE_KEYS}")
        object.__setattr__(self, "value", np.array(self.value, dtype=float))

    @property
    def vector(self) -> bool:
        """b, c, q0 and sat are vectors."""
        return self.key in ("b", "c", "q0", "sat")

    @property
    def matrix(self) -> np.ndarray:
        """The value as it enters the equations (rows x cols, sign applied)."""
        v = self.value.reshape(-1, 1) if self.vector else self.value
        return self.sign * v


@dataclass(frozen=True)
class NativeForm:
    """A slave's mathematics as y = C q + D u + c + G xi, q+ = A q + B u + Bo y + b + F xi."""

    inputs: list[ArraySpec]           #: the slave's input arrays, in order
    outputs: list[ArraySpec]          #: the slave's output arrays, in order
    roles: list[Role]
    nq: int                           #: state size
    h: float                          #: the step the design is for, s
    nxi: int = 0                      #: standard normals per step
    seed: int = 0                     #: the noise generators' seed
    #: the noise streams filling xi in order: (key, count) each, a generator seeded as
    #: numpy.random.default_rng([seed, key]) (default_rng(seed) for key None) drawing its
    #: count of standard normals per step; () is one unkeyed stream of nxi
    streams: tuple[tuple[int | None, int], ...] = ()
    static: bool = False              #: no state: any communication step works
    description: str = ""
    notes: dict[str, str] = field(default_factory=dict)

    @property
    def nu(self) -> int:
        """Number of scalar inputs."""
        return sum(s.size for s in self.inputs)

    @property
    def ny(self) -> int:
        """Number of scalar outputs."""
        return sum(s.size for s in self.outputs)

    @property
    def noise_streams(self) -> tuple[tuple[int | None, int], ...]:
        """The streams of xi, (key, count) each (none without noise)."""
        if not self.nxi:
            return ()
        return self.streams or ((None, self.nxi),)

    @property
    def stream(self) -> int | None:
        """The key of the one keyed stream (an FMU parameter: a vehicle's number), or None."""
        st = self.noise_streams
        return st[0][0] if len(st) == 1 and st[0][0] is not None else None

    def role(self, key: str) -> Role | None:
        """The role with this key, or None (a zero matrix)."""
        return next((r for r in self.roles if r.key == key), None)

    def check(self) -> None:
        """Every matrix fits the sizes; one line naming the role otherwise.

        Raises
        ------
        ValueError
            If a role's shape or range does not fit, or the streams do not fill xi.
        """
        if sum(c for _, c in self.noise_streams) != self.nxi:
            raise ValueError(f"the noise streams draw {sum(c for _, c in self.noise_streams)} "
                             f"normals per step, xi has {self.nxi}")
        rows = {"A": self.nq, "B": self.nq, "Bo": self.nq, "b": self.nq, "F": self.nq,
                "C": self.ny, "D": self.ny, "c": self.ny, "G": self.ny, "q0": self.nq,
                "sat": self.ny}
        cols = {"A": self.nq, "C": self.nq, "Bo": self.ny, "B": self.nu, "D": self.nu,
                "F": self.nxi, "G": self.nxi, "b": 1, "c": 1, "q0": 1, "sat": 1}
        for r in self.roles:
            m = r.matrix
            fits = (r.row0 + m.shape[0] <= rows[r.key] if r.key in ("G", "sat")
                    else m.shape[0] == rows[r.key])
            if not fits:
                raise ValueError(f"native role {r.name} ({r.key}) has {m.shape[0]} rows, the "
                                 f"equations need {rows[r.key]}")
            if r.col0 + m.shape[1] > cols[r.key] or (r.key in ("A", "C", "Bo") and
                                                     m.shape[1] != cols[r.key]):
                raise ValueError(f"native role {r.name} ({r.key}) has columns "
                                 f"{r.col0}..{r.col0 + m.shape[1]}, the equations have "
                                 f"{cols[r.key]}")

    def step(self, q: np.ndarray, u: np.ndarray, xi: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """(y, q+) in numpy: the C code's equations, for tests and references."""
        xi = np.zeros(self.nxi) if xi is None else xi
        y = np.zeros(self.ny)
        qn = np.zeros(self.nq)
        vecs = {"B": u, "D": u, "F": xi, "G": xi, "A": q, "C": q}
        for key in ("C", "D", "c", "G"):
            r = self.role(key)
            if r is None:
                continue
            m = r.matrix
            add = m[:, 0] if r.vector else m @ vecs[key][r.col0:r.col0 + m.shape[1]]
            y[r.row0:r.row0 + m.shape[0]] += add
        sat = self.role("sat")
        if sat is not None:
            rows = slice(sat.row0, sat.row0 + sat.value.size)
            y[rows] = np.minimum(np.maximum(y[rows], -sat.value), sat.value)
        vecs["Bo"] = y
        for key in ("A", "B", "Bo", "b", "F"):
            r = self.role(key)
            if r is None:
                continue
            m = r.matrix
            qn += m[:, 0] if r.vector else m @ vecs[key][r.col0:r.col0 + m.shape[1]]
        return y, qn


class BlockLayout:
    """Where each named array lies in a stacked vector (a slave's inputs or outputs)."""

    def __init__(self, specs: Sequence[ArraySpec]):
        self.slices: dict[str, slice] = {}
        pos = 0
        for s in specs:
            self.slices[s.name] = slice(pos, pos + s.size)
            pos += s.size
        self.size = pos

    def __getitem__(self, name: str) -> slice:
        return self.slices[name]
