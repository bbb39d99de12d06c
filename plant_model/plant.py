"""The sampled plant: vehicles, disturbance and reference exosystems, noisy sensors.

At sample k (time k h) the plant holds s[k] = [x; w; z] and the noise row drawn for k:

    y[k]    = C x[k] + n[k]          ybar[k] = H z[k] + n_z[k]
    e[k]    = H z[k] - C x[k]         (noiseless, for scoring)
    s[k+1]  = Ad s[k] + Bd u[k] + v[k]

Every random number comes from one ``numpy.random.Generator(PCG64(seed))``: per step one
standard normal vector xi[k] of length ns + 2p, drawn in blocks of rows (a block of
rows is the same stream as row-by-row draws), and [v[k]; n[k]; n_z[k]] = L xi[k] with
L = blkdiag(Qd^(1/2), Rd^(1/2)), the symmetric square roots (:mod:`plant_model.noise_factor`:
unique for the matrix, so the same seed gives the same traces on every machine).

``get_state()`` / ``set_state(state)`` (on :class:`Plant` and :class:`NoiseStream`) capture and
restore everything that evolves, as plain Python / numpy values: the sampled state s, the
step counter k, the current noise row, the generator's bit-generator state and the rows of
the current block not yet used. A restored plant draws exactly the same noise afterwards.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy.linalg import block_diag

from .discretization import DiscreteModel
from .noise_factor import psd_sqrt

__all__ = ["NoiseStream", "Plant", "plant_output_layout"]


def _float_array(value: Any, shape: tuple[int, ...], what: str) -> np.ndarray:
    """A float copy of ``value`` with exactly ``shape`` (ValueError naming ``what`` if not)."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "fiu" or arr.shape != shape:
        raise ValueError(f"{what} must be a real array of shape {shape}, "
                         f"got {arr.dtype} of shape {arr.shape}")
    return np.array(arr, dtype=float)


def _count(value: Any, what: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{what} must be a non-negative integer, got {value!r}")
    return int(value)


def _noise_factors(model: DiscreteModel) -> tuple[np.ndarray, np.ndarray]:
    """Transposed factors (Lq', Lr') with Lq Lq' = Qd and Lr Lr' = Rd: the symmetric square
    roots (:func:`plant_model.noise_factor.psd_sqrt`)."""
    return psd_sqrt(model.Qd).T.copy(), psd_sqrt(model.Rd).T.copy()


def _streams(model: DiscreteModel) -> list[tuple[int, np.ndarray, np.ndarray]] | None:
    """(seed key, positions, transposed factor) per independent stream of ``model`` (its
    ``noise_blocks``: vehicles 1..N keyed 1..N, the leader keyed 0, unless ``noise_keys``
    says otherwise), or None for one stream.

    Raises
    ------
    ValueError
        If the blocks do not cover the row or the covariance couples two blocks.
    """
    if not model.noise_blocks:
        return None
    full = block_diag(model.Qd, model.Rd)
    blocks = [np.asarray(b, dtype=np.int64) for b in model.noise_blocks]
    every = np.sort(np.concatenate(blocks))
    if not np.array_equal(every, np.arange(model.noise_dim)):
        raise ValueError("the noise streams must cover every position of the noise row once")
    scale = max(float(np.abs(full).max(initial=0.0)), 1e-300)
    out = []
    for k, idx in enumerate(blocks):
        others = np.setdiff1d(every, idx)
        if others.size and np.abs(full[np.ix_(idx, others)]).max() > 1e-12 * scale:
            raise ValueError(f"noise stream {k + 1} is correlated with the others: the noise "
                             "cannot be drawn per vehicle")
        if model.noise_keys is not None:
            key = int(model.noise_keys[k])
        else:
            key = k + 1 if k < len(blocks) - 1 else 0
        out.append((key, idx, psd_sqrt(full[np.ix_(idx, idx)]).T.copy()))
    return out


def _colour(xi: np.ndarray, factors: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Rows xi L' for standard normal rows xi, L = blkdiag(Lq, Lr) (block by block)."""
    LqT, LrT = factors
    ns = LqT.shape[0]
    out = np.empty_like(xi)
    np.matmul(xi[:, :ns], LqT, out=out[:, :ns])
    np.matmul(xi[:, ns:], LrT, out=out[:, ns:])
    return out


class NoiseStream:
    """Rows [v[k]; n[k]; n_z[k]] for k = 0, 1, ..., drawn lazily in blocks."""

    def __init__(self, model: DiscreteModel, seed: int, block: int = 2048):
        self._dim = model.noise_dim
        self._streams = _streams(model)
        if self._streams is None:
            self._factors = _noise_factors(model)
            self._rngs = [np.random.default_rng(int(seed))]
        else:                         # a fleet's vehicles (and leader) draw their own noise
            self._rngs = [np.random.default_rng([int(seed), key]) for key, _, _ in self._streams]
        self._block = int(block)
        self._buf = np.empty((0, model.noise_dim))
        self._i = 0

    def _draw(self, count: int) -> np.ndarray:
        """``count`` new coloured rows from the generator(s)."""
        if self._streams is None:
            return _colour(self._rngs[0].standard_normal((count, self._dim)), self._factors)
        out = np.empty((count, self._dim))
        for (_, idx, LT), rng in zip(self._streams, self._rngs):
            out[:, idx] = rng.standard_normal((count, idx.size)) @ LT
        return out

    @staticmethod
    def all_rows(model: DiscreteModel, seed: int, steps: int) -> np.ndarray:
        """The first ``steps`` rows at once (same values as drawing them one by one).

        Row k is [v[k]; n[k]; n_z[k]] = L xi[k], L = blkdiag(factors of Qd and Rd).

        Parameters
        ----------
        model : DiscreteModel
            The sampled model (its Qd, Rd and noise dimension).
        seed : int
            Seed of the PCG64 generator.
        steps : int
            Number of rows.

        Returns
        -------
        np.ndarray
            The noise rows, shape (steps, ns + 2 p).
        """
        return NoiseStream(model, seed, block=1)._draw(int(steps))

    def next_row(self) -> np.ndarray:
        """The next row [v[k]; n[k]; n_z[k]], drawing a new block when the current one is used.

        Returns
        -------
        np.ndarray
            A view of shape (ns + 2 p,) into the current block (do not modify it).
        """
        if self._i >= self._buf.shape[0]:
            self._buf = self._draw(self._block)
            self._i = 0
        row = self._buf[self._i]
        self._i += 1
        return row

    def next_rows(self, count: int) -> np.ndarray:
        """The next ``count`` rows at once: the same values as ``count`` calls of
        :meth:`next_row` (a batched engine draws its noise here).

        Parameters
        ----------
        count : int
            Number of rows.

        Returns
        -------
        np.ndarray
            A new array of shape (count, ns + 2 p).
        """
        out = np.empty((int(count), self._dim))
        i = 0
        while i < out.shape[0]:
            if self._i >= self._buf.shape[0]:
                self._buf = self._draw(self._block)
                self._i = 0
            take = min(out.shape[0] - i, self._buf.shape[0] - self._i)
            out[i:i + take] = self._buf[self._i:self._i + take]
            self._i += take
            i += take
        return out

    def get_state(self) -> dict:
        """Everything that evolves, as plain values (copies).

        ``pending`` holds the coloured rows of the current block not yet returned: after
        :meth:`set_state` they come first, then new blocks from ``bit_generator``.

        Returns
        -------
        dict
            Keys ``bit_generator`` (the generator's state), ``pending`` (array of rows),
            ``block`` (rows per draw) and ``dim`` (values per row).
        """
        states = [rng.bit_generator.state for rng in self._rngs]   # fresh dicts of ints
        return {"bit_generator": states[0] if self._streams is None else states,
                "pending": self._buf[self._i:].copy(),
                "block": self._block, "dim": self._dim}

    def set_state(self, state: dict) -> None:
        """Restore a :meth:`get_state` result (validated first: on error nothing changes).

        Parameters
        ----------
        state : dict
            A result of :meth:`get_state` of a stream with the same row length.

        Raises
        ------
        ValueError
            If the row length differs or an entry is invalid.
        """
        if _count(state["dim"], "noise dim") != self._dim:
            raise ValueError(f"the noise state has rows of {state['dim']} values, this stream "
                             f"draws {self._dim}")
        block = _count(state["block"], "noise block size")
        if block < 1:
            raise ValueError("noise block size must be at least 1")
        pending = np.asarray(state["pending"])
        if pending.ndim != 2:
            raise ValueError(f"pending noise rows must be a 2-d array, got shape {pending.shape}")
        pending = _float_array(pending, (pending.shape[0], self._dim), "pending noise rows")
        saved = state["bit_generator"]
        saved = [saved] if self._streams is None else saved
        if not isinstance(saved, list) or len(saved) != len(self._rngs):
            held = len(saved) if isinstance(saved, list) else "no list of"
            raise ValueError(f"the noise state holds {held} generator states, this stream "
                             f"has {len(self._rngs)}")
        rngs = []
        for one in saved:
            rng = np.random.Generator(type(self._rngs[0].bit_generator)())
            try:
                rng.bit_generator.state = one
            except (TypeError, ValueError, KeyError) as exc:
                raise ValueError(f"invalid noise generator state: {exc}") from None
            rngs.append(rng)
        self._rngs, self._block, self._buf, self._i = rngs, block, pending, 0


def plant_output_layout(model: DiscreteModel) -> dict[str, slice]:
    """Slices of the plant's output vector [y, ybar, x, w, z, e].

    Parameters
    ----------
    model : DiscreteModel
        The sampled model (its sizes n, r, l, p).

    Returns
    -------
    dict[str, slice]
        Name -> slice of the output vector of length 3 p + n + r + l.
    """
    p, n, r, l_ = model.p, model.n, model.r, model.l
    names = (("y", p), ("ybar", p), ("x", n), ("w", r), ("z", l_), ("e", p))
    out, i = {}, 0
    for name, size in names:
        out[name] = slice(i, i + size)
        i += size
    return out


class Plant:
    """Sampled plant; ``output`` is the vector [y, ybar, x, w, z, e] at the current k.

    ``out``: an array of 3 p + n + r + l floats to hold ``output`` (updated in place at
    every step; the FMU slave passes its own output buffer, so nothing is copied).
    """

    def __init__(self, model: DiscreteModel, s0: np.ndarray, seed: int,
                 out: np.ndarray | None = None):
        self.model = model
        self.seed = int(seed)
        ns, p = model.ns, model.p
        # C-contiguous copies (Ad, Bd are views into one matrix exponential) for ndarray.dot:
        # it calls the same BLAS gemv as `@` (same products in the same order, same bits)
        # without the matmul ufunc's dispatch, which costs more than the product here
        self._M, self._E, self._Ad, self._Bd = (np.ascontiguousarray(a) for a in
                                                (model.M, model.E, model.Ad, model.Bd))
        self._ns, self._2p = ns, 2 * p
        size = 3 * p + ns
        if out is None:
            out = np.empty(size)
        elif out.shape != (size,):
            raise ValueError(f"plant output buffer has shape {out.shape}, expected ({size},)")
        self.output = out
        # views of output: [M s + noise; s; E s]
        self._o_meas, self._o_s, self._o_e = out[:2 * p], out[2 * p:2 * p + ns], out[2 * p + ns:]
        self.reset(s0)

    def reset(self, s0: np.ndarray) -> None:
        """Restart at k = 0 from the state ``s0`` with a fresh noise stream of the same seed.

        Parameters
        ----------
        s0 : np.ndarray
            Initial true state s(0) = [x0; w0; z0], shape (n + r + l,).
        """
        self.k = 0
        self.s = np.array(s0, dtype=float)
        self._noise = NoiseStream(self.model, self.seed)
        self._row = self._noise.next_row()
        self._refresh()

    def _refresh(self) -> None:
        s = self.s
        self._M.dot(s, out=self._o_meas)
        self._o_meas += self._row[self._ns:]
        self._o_s[:] = s
        self._E.dot(s, out=self._o_e)

    def get_state(self) -> dict:
        """Everything that evolves (copies): k, s, the current noise row, the noise stream.

        Returns
        -------
        dict
            Keys ``k``, ``seed``, ``s``, ``row`` and ``noise`` (:meth:`NoiseStream.get_state`).
        """
        return {"k": self.k, "seed": self.seed, "s": self.s.copy(), "row": self._row.copy(),
                "noise": self._noise.get_state()}

    def set_state(self, state: dict) -> None:
        """Restore a :meth:`get_state` result (validated first: on error nothing changes).

        Parameters
        ----------
        state : dict
            A result of :meth:`get_state` of a plant with the same model and seed.

        Raises
        ------
        ValueError
            If the seed differs or an entry has the wrong type or shape.
        """
        if int(state["seed"]) != self.seed:
            raise ValueError(f"the plant state was drawn with seed {state['seed']}, "
                             f"this plant has seed {self.seed}")
        k = _count(state["k"], "step counter k")
        s = _float_array(state["s"], (self._ns,), "plant state s")
        row = _float_array(state["row"], (self.model.noise_dim,), "noise row")
        self._noise.set_state(state["noise"])
        self.k, self.s, self._row = k, s, row
        self._refresh()

    def step(self, u: np.ndarray) -> None:
        """Advance one step with u held constant: s <- Ad s + Bd u + v[k].

        Parameters
        ----------
        u : np.ndarray
            Control input u[k], shape (m,), held over [k h, (k+1) h).
        """
        s = self._Ad.dot(self.s)            # (Ad s + Bd u) + v, summed in place
        s += self._Bd.dot(u)
        s += self._row[:self._ns]
        self.s = s
        self.k += 1
        self._row = self._noise.next_row()
        self._refresh()
