"""Strong components without cut-offs (issue 13, point 3).

``bottom_sccs`` (traps of workable-reachability) and ``cyclic_states`` (non-progress
cycles of no-dead-states) use scipy's strong components; they agree with networkx on
random graphs and stay exact far past the old limits (20,000 trap states, 500,000
states on cycles), where the networkx code returned the whole region / every survivor.
"""
from __future__ import annotations

import networkx as nx
import numpy as np
from hypothesis import given, settings, strategies as st

from btfsm.verify.system import bottom_sccs, cyclic_states, strong_components


@st.composite
def graphs(draw):
    n = draw(st.integers(1, 25))
    edges = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=60))
    nodes = draw(st.lists(st.integers(0, n - 1), min_size=1, unique=True))
    return n, edges, nodes


def _arrays(edges):
    return (np.array([a for a, _ in edges], np.int64), np.array([b for _, b in edges], np.int64))


@settings(max_examples=300, deadline=None)
@given(graphs())
def test_against_networkx(g):
    n, edges, nodes = g
    src, dst = _arrays(edges)
    full = nx.DiGraph()
    full.add_nodes_from(range(n))
    full.add_edges_from(edges)
    # the partition into SCCs
    lab = strong_components(n, src, dst)
    ours = sorted(sorted(np.flatnonzero(lab == c).tolist()) for c in np.unique(lab))
    assert ours == sorted(sorted(c) for c in nx.strongly_connected_components(full))
    # states on a cycle: non-trivial SCCs and self-loops
    want = sorted(x for c in nx.strongly_connected_components(full)
                  if len(c) > 1 or any(full.has_edge(v, v) for v in c) for x in c)
    assert cyclic_states(n, src, dst).tolist() == want
    # bottom SCCs of the induced sub-graph, ordered by lowest member (the old networkx code)
    sub = full.subgraph(nodes)
    cond = nx.condensation(sub)
    old = sorted((sorted(cond.nodes[c]["members"]) for c in cond.nodes if cond.out_degree(c) == 0),
                 key=lambda scc: scc[0])
    assert bottom_sccs(n, src, dst, nodes) == old


def test_bottom_sccs_past_old_limit():
    # 30,000 trap states: a chain 0 -> 1 -> ... feeding a 3-cycle
    n = 30_000
    src = np.arange(n - 1)
    dst = src + 1
    src = np.concatenate((src, [n - 1]))
    dst = np.concatenate((dst, [n - 3]))
    region = np.arange(n)
    # the old code returned [region] (all 30,000 states) past 20,000
    assert bottom_sccs(n, src, dst, region) == [[n - 3, n - 2, n - 1]]


def test_cyclic_states_past_old_limit():
    # 600,000 states that all lead to a cycle (the old code's approximation past 500,000
    # answered all of them), but only 3 lie on one: a long chain into a 3-cycle
    n = 600_000
    src = np.arange(n - 1)
    dst = src + 1
    src = np.concatenate((src, [n - 1]))
    dst = np.concatenate((dst, [n - 3]))
    assert cyclic_states(n, src, dst).tolist() == [n - 3, n - 2, n - 1]
    # and a big genuine cycle is found whole
    big = cyclic_states(n, np.arange(n), (np.arange(n) + 1) % n)
    assert big.size == n
