"""plant_model.graph: Laplacian/pinning by hand, edge direction, errors, spectrum of L + G."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plant_model.graph import CommunicationGraph, communication_graph, stacked_coupling
from plant_model.linalg_checks import ModelError

# 0 -> 1 (a_10 = 2), 1 -> 2 (a_21 = 0.5), 1 -> 3 (a_31 = 1), 2 -> 3 (a_32 = 3)
EDGES = [(1, 2, 0.5), (1, 3, 1.0), (2, 3, 3.0)]
PIN = {1: 2.0}


@pytest.fixture
def g3() -> CommunicationGraph:
    return communication_graph(3, EDGES, PIN)


def test_hand_worked_matrices(g3):
    np.testing.assert_array_equal(g3.adjacency(), [[0.0, 0.0, 0.0],
                                                   [0.5, 0.0, 0.0],
                                                   [1.0, 3.0, 0.0]])
    np.testing.assert_array_equal(g3.laplacian(), [[0.0, 0.0, 0.0],
                                                   [-0.5, 0.5, 0.0],
                                                   [-1.0, -3.0, 4.0]])
    np.testing.assert_array_equal(g3.pinning_matrix(), np.diag([2.0, 0.0, 0.0]))
    np.testing.assert_array_equal(g3.consensus_matrix(), [[2.0, 0.0, 0.0],
                                                          [-0.5, 0.5, 0.0],
                                                          [-1.0, -3.0, 4.0]])
    # triangular: eigenvalues are the diagonal
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(g3.consensus_matrix()).real),
                               [0.5, 2.0, 4.0], atol=1e-12)


def test_laplacian_acts_as_sum_of_differences(g3):
    x = np.array([1.0, 10.0, 100.0])
    # (L x)_3 = a_31 (x3 - x1) + a_32 (x3 - x2) = 99 + 270
    np.testing.assert_allclose(g3.laplacian() @ x, [0.0, 0.5 * 9.0, 99.0 + 270.0])


def test_normalized_storage_and_digraph(g3):
    assert g3.N == 3
    assert g3.edges == ((1, 2, 0.5), (1, 3, 1.0), (2, 3, 3.0))
    assert g3.pinning == ((1, 2.0),)
    d = g3.digraph()
    assert sorted(d.nodes) == [0, 1, 2, 3]
    assert d[0][1]["weight"] == 2.0 and d[2][3]["weight"] == 3.0
    assert not d.has_edge(3, 2) and not d.has_edge(1, 0)
    assert communication_graph(3, EDGES, [(1, 2.0)]) == g3      # pairs == mapping
    assert communication_graph(3, EDGES, {"1": 2}) == g3        # TOML-style string keys


def test_reversing_an_edge_changes_the_predicted_entries(g3):
    """2 -> 3 (vehicle 3 hears 2) becomes 3 -> 2 (vehicle 2 hears 3)."""
    rev = communication_graph(3, [(1, 2, 0.5), (1, 3, 1.0), (3, 2, 3.0)], PIN)
    diff = rev.laplacian() - g3.laplacian()
    expected = np.zeros((3, 3))
    expected[2, 1] = +3.0     # L[3,2]: vehicle 3 no longer hears 2
    expected[2, 2] = -3.0     # L[3,3]: its in-degree drops by 3
    expected[1, 2] = -3.0     # L[2,3]: vehicle 2 now hears 3
    expected[1, 1] = +3.0     # L[2,2]: its in-degree grows by 3
    np.testing.assert_array_equal(diff, expected)
    for g in (g3, rev):
        np.testing.assert_allclose(g.laplacian().sum(axis=1), 0.0, atol=1e-15)


def test_stacked_coupling_blocks(g3):
    Gam = np.array([[1.0, 2.0], [0.0, 3.0]])
    S = stacked_coupling(g3, Gam)
    assert S.shape == (6, 6)
    np.testing.assert_array_equal(S[2:4, 0:2], 0.5 * Gam)        # A_21 = a_21 Gamma
    np.testing.assert_array_equal(S[4:6, 2:4], 3.0 * Gam)        # A_32 = a_32 Gamma
    np.testing.assert_array_equal(S[0:2, 0:2], -2.0 * Gam)       # pinning only
    np.testing.assert_array_equal(S[4:6, 4:6], -4.0 * Gam)
    np.testing.assert_array_equal(S[0:2, 2:6], 0.0)              # 1 hears nobody
    with pytest.raises(ModelError, match=r"coupling: wrong shape 2x3, expected 2x2"):
        stacked_coupling(g3, np.ones((2, 3)))


@pytest.mark.parametrize("N, edges, pin, words", [
    (0, [], {1: 1.0}, "N = 0 must be at least 1"),
    (4, [(2, 7, 1.0)], {1: 1.0}, "edge 2 -> 7: vehicle 7 does not exist; vehicles are 1..4"),
    (4, [(0, 2, 1.0)], {1: 1.0}, "edge 0 -> 2: vehicle 0 does not exist"),
    (4, [(3, 3, 1.0)], {1: 1.0}, "edge 3 -> 3 is a self-loop"),
    (2, [(1, 2, -1.0)], {1: 1.0}, "edge 1 -> 2: weight -1 must be positive and finite"),
    (2, [(1, 2, 0.0)], {1: 1.0}, "edge 1 -> 2: weight 0 must be positive and finite"),
    (2, [(1, 2, float("nan"))], {1: 1.0}, "edge 1 -> 2: weight nan must be positive"),
    (2, [(1, 2, float("inf"))], {1: 1.0}, "edge 1 -> 2: weight inf must be positive"),
    (2, [(1, 2, 1.0), (1, 2, 2.0)], {1: 1.0}, "edge 1 -> 2 is given twice"),
    (2, [(1, 2, 1.0)], {5: 1.0}, "pinning of vehicle 5: vehicle 5 does not exist; vehicles are 1..2"),
    (2, [(1, 2, 1.0)], {1: 0.0}, "pinning of vehicle 1: weight 0 must be positive"),
    (2, [(1, 2, 1.0)], [(1, 1.0), (1, 2.0)], "pinning of vehicle 1 is given twice"),
    (2, [(1, 2, 1.0)], {}, "no vehicle hears the leader"),
    (4, [(1, 2, 1.0), (3, 4, 1.0), (4, 3, 1.0)], {1: 1.0},
     "vehicles 3, 4 have no path from the leader"),
    (3, [(1, 2, 1.0), (3, 1, 1.0)], {1: 1.0}, "vehicle 3 has no path from the leader"),
    (2, [(1, 2)], {1: 1.0}, "edge #1 (1, 2) is not (from vehicle j, to vehicle i, weight)"),
    (2, [(1.5, 2, 1.0)], {1: 1.0}, "edge 1.5 -> 2: vehicle 1.5 is not a whole number"),
])
def test_bad_graphs_name_the_problem(N, edges, pin, words):
    with pytest.raises(ModelError) as exc:
        communication_graph(N, edges, pin)
    assert words in str(exc.value)


def test_direct_construction_is_validated_too():
    with pytest.raises(ModelError, match="edge 1 -> 1 is a self-loop"):
        CommunicationGraph(2, ((1, 1, 1.0),), ((1, 1.0),))


@st.composite
def rooted_trees(draw):
    """A spanning tree rooted at the leader on a random labelling, plus extra edges.

    Returns (N, order, tree edges, pinning, in-weight of each vehicle, extra edges);
    ``order`` lists the vehicles parents-first."""
    N = draw(st.integers(1, 8))
    order = draw(st.permutations(list(range(1, N + 1))))
    w = st.floats(0.1, 10.0)
    tree, pin, in_weight = [], {}, {}
    for k, i in enumerate(order):
        parent = draw(st.integers(0, k))          # 0 = leader, else an earlier vehicle
        in_weight[i] = draw(w)
        if parent == 0:
            pin[i] = in_weight[i]
        else:
            tree.append((order[parent - 1], i, in_weight[i]))
    pairs = {(j, i) for j, i, _ in tree}
    extra = []
    for j, i in draw(st.lists(st.tuples(st.integers(1, N), st.integers(1, N)), max_size=6)):
        if j != i and (j, i) not in pairs:
            pairs.add((j, i))
            extra.append((j, i, draw(w)))
    return N, order, tree, pin, in_weight, extra


@settings(derandomize=True, max_examples=60, deadline=None)
@given(rooted_trees())
def test_consensus_matrix_spectrum_for_leader_rooted_graphs(case):
    N, order, tree, pin, in_weight, extra = case
    # a pure tree: every vehicle hears exactly one node, so L + G is lower triangular in
    # the parents-first order with the in-weights on the diagonal: those are its
    # eigenvalues, all positive
    g = communication_graph(N, tree, pin)
    idx = np.array(order) - 1
    M = g.consensus_matrix()[np.ix_(idx, idx)]
    np.testing.assert_array_equal(np.triu(M, 1), 0.0)
    np.testing.assert_array_equal(np.diag(M), [in_weight[i] for i in order])
    assert np.linalg.eigvals(g.consensus_matrix()).real.min() > 0.0
    # with extra edges: still every eigenvalue in the open right half-plane
    g2 = communication_graph(N, tree + extra, pin)
    assert np.linalg.eigvals(g2.consensus_matrix()).real.min() > 1e-9
    np.testing.assert_allclose(g2.laplacian().sum(axis=1), 0.0, atol=1e-12)
