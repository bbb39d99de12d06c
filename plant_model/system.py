"""The paper's linear system (eq. 4-6) with its noise and cost weights, validated.

Continuous time, states stacked as in the paper:

    vehicles      x' = A x + B1 u + B2 w + Bz z + m,   y    = C x + n
    disturbance   w' = K w + m_w
    reference     z' = F z + m_z,               ybar = H z + n_z
    tracking error  e = H z - C x
    cost rate       e' Q e + u' R u

Bz (zero by default, as in the paper's single-vehicle example) carries the leader into the
vehicles' dynamics: in a fleet on a communication graph the pinning term a_i0 (x_0 - x_i)
of eq. 1 brings the leader's state x_0 = T z into the vehicles that hear it
(:mod:`plant_model.fleet`).

Noise intensities (power spectral densities) W_x, W_w, W_z of m, m_w, m_z and
V_y, V_ybar of n, n_z; see :mod:`plant_model.discretization` for what a sample sees.
Nothing here assumes a size: n states, m inputs, r disturbances, p outputs, l reference
states.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from .linalg_checks import (
    ModelError,
    as_float,
    as_matrix,
    as_square,
    as_vector,
    check_symmetric_pd,
    check_symmetric_psd,
)

__all__ = ["LinearSystem", "NOISE_CONVENTIONS", "MATRIX_NAMES"]

#: ``intensity``: W, V are continuous-time intensities (docs/theory.md section 4); ``per_sample``:
#: W is the covariance of the process noise added per step and V the covariance of
#: each measurement sample, whatever h is (a different experiment, named as such).
NOISE_CONVENTIONS = ("intensity", "per_sample")

MATRIX_NAMES = ("A", "B1", "B2", "Bz", "C", "F", "H", "K", "Q", "R",
                "W_x", "W_w", "W_z", "V_y", "V_ybar")


@dataclass(frozen=True)
class LinearSystem:
    """Matrices of the closed-loop problem; construct with :meth:`from_mapping`."""

    A: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    C: np.ndarray
    F: np.ndarray
    H: np.ndarray
    K: np.ndarray
    Bz: np.ndarray
    x0: np.ndarray
    w0: np.ndarray
    z0: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    W_x: np.ndarray
    W_w: np.ndarray
    W_z: np.ndarray
    V_y: np.ndarray
    V_ybar: np.ndarray
    noise_convention: str = "intensity"
    meta: Mapping[str, Any] = field(default_factory=dict, compare=False)

    # sizes -----------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of vehicle states."""
        return self.A.shape[0]

    @property
    def m(self) -> int:
        """Number of control inputs."""
        return self.B1.shape[1]

    @property
    def r(self) -> int:
        """Number of disturbance states."""
        return self.K.shape[0]

    @property
    def p(self) -> int:
        """Number of measured / tracked outputs."""
        return self.C.shape[0]

    @property
    def l(self) -> int:  # noqa: E743 - the paper's name
        """Number of reference (virtual leader) states."""
        return self.F.shape[0]

    @property
    def dims(self) -> dict[str, int]:
        """The sizes n, m, r, p, l by name."""
        return {"n": self.n, "m": self.m, "r": self.r, "p": self.p, "l": self.l}

    # construction ---------------------------------------------------------
    @classmethod
    def from_mapping(cls, d: Mapping[str, Any]) -> LinearSystem:
        """Build and validate from a mapping of names to nested lists / arrays.

        Scalars are accepted for Q, R and the noise matrices and mean ``scalar * I``.

        Parameters
        ----------
        d : Mapping[str, Any]
            Entries named as the fields (A, B1, B2, C, F, H, K required; Bz, x0, w0, z0,
            Q, R, the noise intensities, ``noise_convention`` and ``meta`` optional).

        Returns
        -------
        LinearSystem
            The validated system.

        Raises
        ------
        ModelError
            Naming the first problem found (unknown or missing entry, wrong shape, value
            not finite, Q or R not positive definite, a noise matrix not positive
            semidefinite, unknown noise convention).
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ModelError(f"unknown system entries: {', '.join(unknown)}")
        missing = [k for k in ("A", "B1", "B2", "C", "F", "H", "K") if k not in d]
        if missing:
            raise ModelError(f"missing system matrices: {', '.join(missing)}")
        A = as_square("A", d["A"])
        n = A.shape[0]
        B1 = as_matrix("B1", d["B1"], (n, None))
        m = B1.shape[1]
        B2 = as_matrix("B2", d["B2"], (n, None))
        r = B2.shape[1]
        C = as_matrix("C", d["C"], (None, n))
        p = C.shape[0]
        F = as_square("F", d["F"])
        l_ = F.shape[0]
        H = as_matrix("H", d["H"], (p, l_))
        K = as_matrix("K", d["K"], (r, r))
        Bz = as_matrix("Bz", d.get("Bz", np.zeros((n, l_))), (n, l_))

        def square(name: str, size: int, default: float) -> np.ndarray:
            v = d.get(name, default)
            if np.ndim(v) == 0:
                return as_float(name, v) * np.eye(size)
            return as_matrix(name, v, (size, size))

        Q = square("Q", p, 1.0)
        R = square("R", m, 1.0)
        check_symmetric_pd("Q", Q)
        check_symmetric_pd("R", R)
        noise = {}
        for name, size in (("W_x", n), ("W_w", r), ("W_z", l_), ("V_y", p), ("V_ybar", p)):
            M = square(name, size, 0.0)
            check_symmetric_psd(name, M)
            noise[name] = M
        conv = d.get("noise_convention", "intensity")
        if conv not in NOISE_CONVENTIONS:
            raise ModelError(
                f"noise_convention {conv!r} is not one of {', '.join(NOISE_CONVENTIONS)}"
            )
        return cls(
            A=A, B1=B1, B2=B2, C=C, F=F, H=H, K=K, Bz=Bz,
            x0=as_vector("x0", d.get("x0", np.zeros(n)), n),
            w0=as_vector("w0", d.get("w0", np.zeros(r)), r),
            z0=as_vector("z0", d.get("z0", np.zeros(l_)), l_),
            Q=Q, R=R, noise_convention=conv, meta=dict(d.get("meta", {})), **noise,
        )

    def to_mapping(self) -> dict[str, Any]:
        """Plain-python (JSON-ready) form, the inverse of :meth:`from_mapping`.

        Returns
        -------
        dict[str, Any]
            Every field, arrays as nested lists; ``meta`` only when it is not empty.
        """
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray):
                out[f.name] = v.tolist()
            elif f.name == "meta":
                if v:
                    out[f.name] = dict(v)
            else:
                out[f.name] = v
        return out

    def with_changes(self, **kw: Any) -> LinearSystem:
        """A re-validated copy with some entries replaced.

        Parameters
        ----------
        **kw : Any
            Entries to replace, named as in :meth:`from_mapping`.

        Returns
        -------
        LinearSystem
            The new, validated system.

        Raises
        ------
        ModelError
            If the changed entries do not make a valid system.
        """
        d = self.to_mapping()
        d.update(kw)
        return LinearSystem.from_mapping(d)

    def without_noise(self) -> LinearSystem:
        """The same system with every noise intensity set to zero.

        Returns
        -------
        LinearSystem
            A copy with W_x = W_w = W_z = V_y = V_ybar = 0.
        """
        z = {k: np.zeros_like(getattr(self, k)) for k in ("W_x", "W_w", "W_z", "V_y", "V_ybar")}
        return replace(self, **z)

    # stacked continuous model --------------------------------------------
    def augmented(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Continuous model of the true state s = [x; w; z].

        s' = Ac s + Bc u + noise with intensity Wc, where
        Ac = [[A, B2, Bz], [0, K, 0], [0, 0, F]], Bc = [B1; 0; 0],
        Wc = blkdiag(W_x, W_w, W_z).

        Returns
        -------
        Ac : np.ndarray
            State matrix, (n + r + l) x (n + r + l), 1/s.
        Bc : np.ndarray
            Input matrix, (n + r + l) x m.
        Wc : np.ndarray
            Process noise intensity, (n + r + l) x (n + r + l).
        """
        n, r, l_, m = self.n, self.r, self.l, self.m
        ns = n + r + l_
        Ac = np.zeros((ns, ns))
        Ac[:n, :n] = self.A
        Ac[:n, n:n + r] = self.B2
        Ac[:n, n + r:] = self.Bz
        Ac[n:n + r, n:n + r] = self.K
        Ac[n + r:, n + r:] = self.F
        Bc = np.zeros((ns, m))
        Bc[:n] = self.B1
        Wc = np.zeros((ns, ns))
        Wc[:n, :n] = self.W_x
        Wc[n:n + r, n:n + r] = self.W_w
        Wc[n + r:, n + r:] = self.W_z
        return Ac, Bc, Wc

    def known_reference_mask(self) -> np.ndarray:
        """Boolean mask over z of the reference states that are deterministic and known.

        A planned leader path (no process noise on a state, and no noise-driven state
        feeding it through F) is known to every vehicle from z(0): its estimate is
        propagated exactly instead of filtered. The largest such set D satisfies
        W_z[D, :] = 0 and F[D, not D] = 0.

        Returns
        -------
        np.ndarray
            Boolean mask of shape (l,), True on the states of D.
        """
        known = ~np.any(self.W_z != 0.0, axis=1)
        while True:
            feeds = np.any(self.F[np.ix_(known, ~known)] != 0.0, axis=1)
            if not feeds.any():
                return known
            idx = np.flatnonzero(known)
            known[idx[feeds]] = False

    def error_matrix(self) -> np.ndarray:
        """E with e = E s = H z - C x for s = [x; w; z].

        Returns
        -------
        np.ndarray
            E = [-C, 0, H], p x (n + r + l).
        """
        E = np.zeros((self.p, self.n + self.r + self.l))
        E[:, :self.n] = -self.C
        E[:, self.n + self.r:] = self.H
        return E

    def measurement_matrix(self) -> np.ndarray:
        """M with [y; ybar] = M s + noise, M = [[C, 0, 0], [0, 0, H]].

        Returns
        -------
        np.ndarray
            M, 2 p x (n + r + l).
        """
        n, r = self.n, self.r
        M = np.zeros((2 * self.p, n + r + self.l))
        M[:self.p, :n] = self.C
        M[self.p:, n + r:] = self.H
        return M

    def initial_state(self) -> np.ndarray:
        """s(0) = [x0; w0; z0].

        Returns
        -------
        np.ndarray
            The initial true state, shape (n + r + l,).
        """
        return np.concatenate([self.x0, self.w0, self.z0])
