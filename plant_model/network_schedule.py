"""A switching topology for the acoustic network: graphs with the times they take over
(the paper's eq. 1, N_i^t). Validated here; running it is future work (docs/network.md)."""
from __future__ import annotations

from typing import Any

from .linalg_checks import ModelError
from .network import _number, _vehicle

__all__ = ["check_schedule"]


def check_schedule(entries: Any, N: int) -> list[tuple[float, list[tuple[int, int, float]]]]:
    """A switching topology: graphs with the times they take over (eq. 1's N_i^t).

    Parameters
    ----------
    entries : Any
        ``[{t, edges = [[j, i, a_ij], ...]}, ...]``, t in s strictly increasing from 0.
    N : int
        Number of vehicles.

    Returns
    -------
    list[tuple[float, list[tuple[int, int, float]]]]
        (switch time, edges) in order.

    Raises
    ------
    ModelError
        One line naming the entry: decreasing or repeated times, a first time other than 0,
        a vehicle that does not exist, a self-loop or a negative weight.
    """
    if not isinstance(entries, (list, tuple)) or not entries:
        raise ModelError("[network] schedule must be a non-empty list of {t, edges}")
    out: list[tuple[float, list[tuple[int, int, float]]]] = []
    for n, entry in enumerate(entries, start=1):
        where = f"[network] schedule entry {n}"
        if not isinstance(entry, dict) or "t" not in entry or "edges" not in entry:
            raise ModelError(f"{where}: needs a table with t and edges")
        t = _number(f"{where}: t", entry["t"])
        if n == 1 and t != 0.0:
            raise ModelError(f"{where}: the first graph must start at t = 0, not {t:g} s")
        if out and t <= out[-1][0]:
            raise ModelError(f"{where}: t = {t:g} s does not come after the previous "
                             f"switch at {out[-1][0]:g} s (switch times must increase)")
        edges = []
        for e in entry["edges"]:
            if not isinstance(e, (list, tuple)) or len(e) != 3:
                raise ModelError(f"{where}: edge {e!r} is not [j, i, a_ij]")
            j = _vehicle(N, e[0], f"{where}, edge {list(e)}")
            i = _vehicle(N, e[1], f"{where}, edge {list(e)}")
            if j == "leader" or i == "leader":
                raise ModelError(f"{where}, edge {list(e)}: edges join vehicles; the leader's "
                                 "links are the pinning")
            if j == i:
                raise ModelError(f"{where}, edge {list(e)}: a self-loop")
            a = _number(f"{where}, edge {list(e)}: weight", e[2])
            if a < 0.0:
                raise ModelError(f"{where}, edge {list(e)}: negative weight {a:g}")
            edges.append((int(j), int(i), a))
        out.append((t, edges))
    return out
