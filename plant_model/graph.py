"""Communication graph of the formation: weighted digraph, Laplacian and pinning (eq. 1-2).

Nodes: 0 is the virtual leader, 1..N the vehicles (vehicles are numbered 1..N in every
argument and message; arrays are 0-based, row i-1 is vehicle i).

Convention: an edge j -> i with weight a_ij > 0 means vehicle i hears vehicle j
(information flows from j to i). The adjacency matrix is Adj[i, j] = a_ij (row = the
listener), and the Laplacian is the in-degree Laplacian

    L = D_in - Adj,     D_in = diag(sum_j a_ij)   (row sums of Adj),

so (L x)_i = sum_j a_ij (x_i - x_j) and every row of L sums to zero. The pinning matrix
is G = diag(a_i0) with a_i0 > 0 exactly when vehicle i hears the leader (edge 0 -> i).
Weights are dimensionless gains.

With the consensus protocol coupling gain Gamma (p x p), vehicle i's dynamics (eq. 1)

    x_i' = A_ii x_i + sum_j a_ij Gamma (x_j - x_i) + a_i0 Gamma (x_0 - x_i) + B1i u_i + ...

stack over the N vehicles to x' = (I_N kron A_ii - (L + G) kron Gamma) x + (G 1 kron Gamma)
x_0 + ...; :func:`stacked_coupling` returns the neighbour + pinning part
-(L + G) kron Gamma, whose off-diagonal blocks are the paper's A_ij = a_ij Gamma.

If every vehicle has a directed path from the leader, every eigenvalue of L + G has a
positive real part (so -(L + G) kron Gamma is Hurwitz for Gamma = I); the constructor
refuses graphs where some vehicle cannot be reached from the leader.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .linalg_checks import ModelError, as_square

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["CommunicationGraph", "communication_graph", "stacked_coupling"]


def _vehicle_index(value: Any, what: str) -> int:
    """A vehicle number; digit strings are accepted (TOML table keys are strings)."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(value, str) and value.strip().isdigit():
        return int(value)
    raise ModelError(f"{what}: vehicle {value!r} is not a whole number")


def _weight(value: Any, what: str) -> float:
    if isinstance(value, (bool, str, bytes)):       # "1.0" is text, not a weight
        raise ModelError(f"{what}: weight {value!r} is not a number")
    try:
        w = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{what}: weight {value!r} is not a number") from None
    if not math.isfinite(w) or w <= 0.0:
        raise ModelError(f"{what}: weight {w:g} must be positive and finite")
    return w


def _vehicles_text(nodes: Iterable[int]) -> str:
    nodes = sorted(nodes)
    if len(nodes) == 1:
        return f"vehicle {nodes[0]} has"
    return f"vehicles {', '.join(map(str, nodes))} have"


def _parse(N: Any, edges: Any, pinning: Any) -> tuple[int, tuple[tuple[int, int, float], ...],
                                                     tuple[tuple[int, float], ...]]:
    """Validate and normalize; returns (N, sorted edges, sorted pinning)."""
    if isinstance(N, bool) or not isinstance(N, (int, np.integer)):
        raise ModelError(f"graph: the number of vehicles N = {N!r} is not a whole number")
    N = int(N)
    if N < 1:
        raise ModelError(f"graph: the number of vehicles N = {N} must be at least 1")
    span = f"vehicles are 1..{N}"

    out_edges: dict[tuple[int, int], float] = {}
    for k, item in enumerate(edges):
        try:
            j_raw, i_raw, w_raw = item
        except (TypeError, ValueError):
            raise ModelError(
                f"graph: edge #{k + 1} {item!r} is not (from vehicle j, to vehicle i, weight)"
            ) from None
        label = f"edge {j_raw} -> {i_raw}"
        j = _vehicle_index(j_raw, label)
        i = _vehicle_index(i_raw, label)
        for v in (j, i):
            if not 1 <= v <= N:
                hint = (" (the leader, node 0, is connected through the pinning weights)"
                        if v == 0 else "")
                raise ModelError(f"{label}: vehicle {v} does not exist; {span}{hint}")
        if i == j:
            raise ModelError(f"{label} is a self-loop")
        w = _weight(w_raw, label)
        if (j, i) in out_edges:
            raise ModelError(f"{label} is given twice")
        out_edges[(j, i)] = w

    if isinstance(pinning, Mapping):
        pin_items = list(pinning.items())
    else:
        try:
            pin_items = [tuple(p) for p in pinning]
        except TypeError:
            raise ModelError(
                f"graph: pinning {pinning!r} must be a mapping {{vehicle: a_i0}} or "
                "pairs (vehicle, a_i0)"
            ) from None
    pins: dict[int, float] = {}
    for item in pin_items:
        if len(item) != 2:
            raise ModelError(f"graph: pinning entry {item!r} is not (vehicle, a_i0)")
        i_raw, w_raw = item
        label = f"pinning of vehicle {i_raw}"
        i = _vehicle_index(i_raw, label)
        if not 1 <= i <= N:
            raise ModelError(f"{label}: vehicle {i} does not exist; {span}")
        w = _weight(w_raw, label)
        if i in pins:
            raise ModelError(f"{label} is given twice")
        pins[i] = w
    if not pins:
        raise ModelError(
            "graph: no vehicle hears the leader; give at least one pinning weight a_i0 > 0"
        )

    import networkx as nx  # imported where used: a single vehicle needs no graph

    g = nx.DiGraph()
    g.add_nodes_from(range(N + 1))
    g.add_edges_from(out_edges)
    g.add_edges_from((0, i) for i in pins)
    unreached = set(range(1, N + 1)) - nx.descendants(g, 0)
    if unreached:
        raise ModelError(
            f"graph: {_vehicles_text(unreached)} no path from the leader: no chain of edges "
            f"leads to them from a pinned vehicle (pinned: "
            f"{', '.join(map(str, sorted(pins)))}); the formation cannot track the leader"
        )
    return (N, tuple((j, i, w) for (j, i), w in sorted(out_edges.items())),
            tuple(sorted(pins.items())))


@dataclass(frozen=True)
class CommunicationGraph:
    """Who hears whom: ``edges`` (j, i, a_ij) for j -> i, ``pinning`` (i, a_i0); 1-based.

    Build it with :func:`communication_graph`; the constructor validates too (see the
    module docstring for the conventions).
    """

    N: int
    edges: tuple[tuple[int, int, float], ...]
    pinning: tuple[tuple[int, float], ...]

    def __post_init__(self) -> None:
        N, edges, pinning = _parse(self.N, self.edges, self.pinning)
        object.__setattr__(self, "N", N)
        object.__setattr__(self, "edges", edges)
        object.__setattr__(self, "pinning", pinning)

    def digraph(self) -> nx.DiGraph:
        """The graph as a networkx digraph, leader included.

        Nodes 0 (leader, ``role`` 'leader') .. N (``role`` 'vehicle'); edges j -> i (and
        0 -> i) with attribute ``weight`` = a_ij (a_i0).

        Returns
        -------
        nx.DiGraph
            A new digraph.
        """
        import networkx as nx

        g = nx.DiGraph()
        g.add_node(0, role="leader")
        g.add_nodes_from(range(1, self.N + 1), role="vehicle")
        g.add_weighted_edges_from(self.edges)
        g.add_weighted_edges_from((0, i, w) for i, w in self.pinning)
        return g

    def adjacency(self) -> np.ndarray:
        """N x N adjacency, [i-1, j-1] = a_ij (row = the vehicle that listens).

        Returns
        -------
        np.ndarray
            Adj, N x N (the leader is not included).
        """
        # nx.to_numpy_array gives M[u, v] = weight of u -> v, i.e. M[j-1, i-1] = a_ij.
        import networkx as nx

        sub = self.digraph().subgraph(range(1, self.N + 1))
        M = nx.to_numpy_array(sub, nodelist=range(1, self.N + 1), weight="weight")
        return M.T

    def laplacian(self) -> np.ndarray:
        """In-degree Laplacian L = D_in - Adj (N x N), (L x)_i = sum_j a_ij (x_i - x_j).

        Built as ``nx.laplacian_matrix`` of the *reversed* follower subgraph: for a
        digraph networkx returns the out-degree Laplacian D_out - M with M[u, v] = weight
        of u -> v; reversing every edge j -> i into i -> j makes M = Adj and D_out = D_in.

        Returns
        -------
        np.ndarray
            L, N x N; every row sums to zero.
        """
        import networkx as nx

        sub = self.digraph().subgraph(range(1, self.N + 1))
        L = nx.laplacian_matrix(sub.reverse(copy=True), nodelist=range(1, self.N + 1),
                                weight="weight")
        return np.asarray(L.toarray(), dtype=float)

    def pinning_matrix(self) -> np.ndarray:
        """G = diag(a_i0) (N x N); a_i0 = 0 for vehicles that do not hear the leader.

        Returns
        -------
        np.ndarray
            G, N x N.
        """
        g = np.zeros(self.N)
        for i, w in self.pinning:
            g[i - 1] = w
        return np.diag(g)

    def consensus_matrix(self) -> np.ndarray:
        """L + G (N x N); all its eigenvalues have positive real part (module docstring).

        Returns
        -------
        np.ndarray
            L + G, N x N.
        """
        return self.laplacian() + self.pinning_matrix()


def communication_graph(N: int, edges: Iterable[Any], pinning: Any) -> CommunicationGraph:
    """Validated communication graph of N vehicles.

    Parameters
    ----------
    N : int
        Number of vehicles (numbered 1..N).
    edges : Iterable[Any]
        Triples (from vehicle j, to vehicle i, weight a_ij > 0), meaning i hears j.
    pinning : Any
        Mapping {i: a_i0} or iterable of (i, a_i0): the vehicles that hear the leader
        (vehicle numbers may be digit strings, as TOML table keys are).

    Returns
    -------
    CommunicationGraph
        The graph with sorted, normalized edges and pinning weights.

    Raises
    ------
    ModelError
        Naming the offending vehicle or edge for: N < 1, a vehicle outside 1..N, a
        self-loop, a weight that is not positive and finite, a duplicate edge or pinning
        entry, no pinned vehicle, or a vehicle with no directed path from the leader.
    """
    return CommunicationGraph(*_parse(N, edges, pinning))


def stacked_coupling(graph: CommunicationGraph, coupling: Any) -> np.ndarray:
    """-(L + G) kron Gamma (N p x N p): neighbour + pinning part of the stacked A (eq. 1-2).

    Block (i, j), j != i, is a_ij Gamma (the paper's A_ij); block (i, i) is
    -(sum_j a_ij + a_i0) Gamma, to be added to A_ii.

    Parameters
    ----------
    graph : CommunicationGraph
        The validated graph of N vehicles.
    coupling : Any
        The p x p consensus gain Gamma (nested lists or an array).

    Returns
    -------
    np.ndarray
        -(L + G) kron Gamma, N p x N p.

    Raises
    ------
    ModelError
        If ``coupling`` is not a finite square matrix.
    """
    Gam = as_square("coupling", coupling)
    return -np.kron(graph.consensus_matrix(), Gam)
