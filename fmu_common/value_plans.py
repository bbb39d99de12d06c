"""Batched fmi2GetReal / fmi2SetReal for :class:`~fmu_common.slave_base.ArraySlave`.

pythonfmu's fmi2GetReal / fmi2SetReal call get_real(vrs) / set_real(vrs, values) with a new
list of value references each time; a co-simulation master passes the same few lists at
every step. A plan (a closure over one slice of a buffer) is made once per list and found
again by the list's first value reference: one dict lookup and one list comparison per
call. Outputs are checked for nan / inf (one ``sum``) when computed, not per call.
"""
from __future__ import annotations

import struct
from collections.abc import Callable

import numpy as np
from pythonfmu import Fmi2Causality, Real

__all__ = ["PlannedAccess"]


class PlannedAccess:
    """Mixin: ``get_real`` / ``set_real`` through cached plans (see the module docstring).

    The slave provides ``_in``, ``_out`` (buffers), ``_vr_in``, ``_vr_out`` (first value
    references), ``_feeds``, ``_dirty``, ``_initialized``, ``compute_outputs``,
    ``_early_outputs``, ``_refresh_outputs`` and ``_check_inputs``; it calls
    :meth:`_init_plans` in ``__init__``.
    """

    def _init_plans(self) -> None:
        self._in_bytes = memoryview(self._in).cast("B")     # what set plans write into
        # plans by tuple of value references, and by first reference: (list, plan)
        self._get_plans: dict[tuple, Callable[[], list]] = {}
        self._set_plans: dict[tuple, Callable[[list], None]] = {}
        self._get_index: dict[int, tuple[list, Callable[[], list]]] = {}
        self._set_index: dict[int, tuple[list, Callable[[list], None]]] = {}
        self._bind_fast_paths()

    # pythonfmu's fmi2GetReal / fmi2SetReal call get_real(vrs) / set_real(vrs, values) with a
    # new list of value references each time; a co-simulation master passes the same few
    # lists at every step. A plan (a closure over one slice of a buffer) is made once per
    # list and found again by the list's first value reference: one dict lookup and one
    # list comparison per call (hashing tuple(vrs) cost about twice that). Lists that share
    # a first reference fall back to a dict keyed by the whole tuple.
    _PLAN_CACHE_SIZE = 256

    def _outputs_view(self, buf: np.ndarray) -> np.ndarray:
        """``buf`` (a view of the outputs), computed and checked first if stale
        (``_refresh_outputs``: a non-finite output is logged, the next step refused)."""
        if self._dirty and self._initialized:
            self._refresh_outputs()
        return buf

    def get_real(self, vrs: list[int]) -> list[float]:
        """fmi2GetReal: the values of the Real variables ``vrs`` (outputs computed lazily).

        Parameters
        ----------
        vrs : list[int]
            Value references.

        Returns
        -------
        list[float]
            Their values, in the order of ``vrs``.

        Raises
        ------
        TypeError
            If a value reference is not a Real variable.
        """
        # shadowed on every instance by the closure of _bind_fast_paths (same result)
        return self._get_planned(vrs)

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        """fmi2SetReal: set the Real variables ``vrs`` (a non-finite input refuses the next step).

        Parameters
        ----------
        vrs : list[int]
            Value references.
        values : list[float]
            Their new values, in the order of ``vrs``.

        Raises
        ------
        TypeError
            If a value reference is not a Real variable.
        """
        # shadowed on every instance by the closure of _bind_fast_paths (same result)
        self._set_planned(vrs, values)

    def _bind_fast_paths(self) -> None:
        """Set ``get_real`` / ``set_real`` on the instance: closures over the plan indexes.

        pythonfmu calls them by name on the instance (PyObject_CallMethod), which finds
        a function in the instance's dict before the class's method: no bound method is
        made per call and the closures read cells instead of attributes of ``self``.
        """
        get_index, set_index = self._get_index, self._set_index
        get_planned, set_planned = self._get_planned, self._set_planned

        def get_real(vrs: list[int]) -> list[float]:
            try:
                key, plan = get_index[vrs[0]]
            except (IndexError, KeyError):
                return get_planned(vrs)
            if key != vrs:
                return get_planned(vrs)
            return plan()

        def set_real(vrs: list[int], values: list[float]) -> None:
            try:
                key, plan = set_index[vrs[0]]
            except (IndexError, KeyError):
                return set_planned(vrs, values)
            if key != vrs:
                return set_planned(vrs, values)
            plan(values)

        self.get_real, self.set_real = get_real, set_real

    def _get_planned(self, vrs: list[int]) -> list[float]:
        plan = self._cached_plan(vrs, self._get_plans, self._get_index, self._plan_get)
        return plan()

    def _set_planned(self, vrs: list[int], values: list[float]) -> None:
        plan = self._cached_plan(vrs, self._set_plans, self._set_index, self._plan_set)
        plan(values)

    def _cached_plan(self, vrs: list[int], plans: dict, index: dict, make: Callable) -> Callable:
        key = tuple(vrs)
        plan = plans.get(key)
        if plan is None:
            plan = make(vrs)
            if len(plans) >= self._PLAN_CACHE_SIZE:
                plans.clear()
            plans[key] = plan
        if vrs:
            if len(index) >= self._PLAN_CACHE_SIZE:
                index.clear()
            index[vrs[0]] = (list(vrs), plan)
        return plan

    def _contiguous(self, vrs: list[int], first: int | None, size: int) -> tuple[int, int] | None:
        if first is None or not vrs:
            return None
        a = vrs[0] - first
        if a < 0 or a + len(vrs) > size:
            return None
        if any(vr != vrs[0] + j for j, vr in enumerate(vrs)):
            return None
        return a, a + len(vrs)

    def _plan_get(self, vrs: list[int]) -> Callable[[], list]:
        span = self._contiguous(vrs, self._vr_out, self._out.size)
        if span is not None:
            view = self._out[span[0]:span[1]]        # a view: the buffer is updated in place

            def plan() -> list:
                if self._dirty:                             # self._outputs_view, inlined
                    if self._initialized:
                        self._refresh_outputs()             # checked once per computation
                    else:
                        self._early_outputs()
                return view.tolist()
        else:
            self._check_refs("fmi2GetReal", vrs, Real, "a Real")
            getters = [self.vars[vr].getter for vr in vrs]
            outputs = any(self.vars[vr].causality == Fmi2Causality.output for vr in vrs)

            def plan() -> list:
                if outputs and self._dirty and not self._initialized:
                    self._early_outputs()
                return [float(g()) for g in getters]
        return plan

    def _plan_set(self, vrs: list[int]) -> Callable[[list], None]:
        span = self._contiguous(vrs, self._vr_in, self._in.size)
        if span is not None:
            a, b = span
            # struct writes the doubles into the buffer about twice as fast as numpy converts
            # a list (the same IEEE values: PyFloat_AsDouble either way)
            pack, mem, offset = struct.Struct(f"={b - a}d").pack_into, self._in_bytes, a * 8
            check = self._check_inputs

            if self._feeds[a:b].any():
                def plan(values: list) -> None:
                    pack(mem, offset, *values)
                    self._dirty = True
                    total = sum(values)
                    if total - total != 0.0:          # some value is nan or +-inf (or overflow)
                        check()
            else:
                def plan(values: list) -> None:
                    pack(mem, offset, *values)
                    total = sum(values)
                    if total - total != 0.0:
                        check()
        else:
            self._check_refs("fmi2SetReal", vrs, Real, "a Real")
            self._check_settable("fmi2SetReal", vrs)
            setters = [self.vars[vr].setter for vr in vrs]

            def plan(values: list) -> None:
                for s, v in zip(setters, values):
                    s(v)
        return plan

