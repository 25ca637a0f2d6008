"""Program (34): assignment against the paper's enumeration."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_crossing_scene
from hypothesis import given, settings
from hypothesis import strategies as st

import direct
from direct.geodesics import grid_distances
from direct.grid import build_graph
from direct.matching import brute_force, solve, solve_flow
from direct.metric import get_metric
from direct.penalty import domains


@st.composite
def cost_tables(draw):
    npos = draw(st.integers(0, 4))
    nneg = draw(st.integers(0, 4))
    pos = st.floats(0.0, 10.0, allow_nan=False)
    A = np.array(draw(st.lists(pos, min_size=npos * nneg, max_size=npos * nneg))).reshape(npos, nneg)
    return A, np.array(draw(st.lists(pos, min_size=npos, max_size=npos))), np.array(
        draw(st.lists(pos, min_size=nneg, max_size=nneg))
    )


@settings(max_examples=300, deadline=None)
@given(cost_tables())
def test_assignment_equals_enumeration(tables):
    A, a0, b0 = tables
    value, pairs = solve(A, a0, b0)
    assert value == pytest.approx(brute_force(A, a0, b0), abs=1e-9)
    # the pairs are a valid element of V (eqs. (35), (36)): every point used exactly once
    plus = [i for i, _ in pairs if i is not None]
    minus = [j for _, j in pairs if j is not None]
    assert sorted(plus) == list(range(len(a0)))
    assert sorted(minus) == list(range(len(b0)))
    # and their cost is the value
    cost = sum(A[i, j] if (i is not None and j is not None) else (a0[i] if i is not None else b0[j]) for i, j in pairs)
    assert cost == pytest.approx(value, abs=1e-9)


def test_boundary_versus_pairing_examples():
    assert solve([[1.0]], [0.4], [0.7]) == (1.0, [(0, 0)])
    assert solve([[1.0]], [0.4], [0.5])[0] == pytest.approx(0.9)
    assert solve(np.zeros((0, 0)), [], []) == (0.0, [])


@pytest.mark.parametrize("seed", range(3))
def test_assignment_equals_enumeration_on_grid_distances(seed):
    sc = random_crossing_scene(seed + 10, n_comp=2, n_vert=6, min_crossings=3, max_crossings=7)
    met = get_metric("G")
    for dom in domains(sc, direct.find_crossings(sc)):
        g = build_graph(dom, met, resolution=40)
        T, _ = grid_distances(g)
        pos, neg = 1 + np.flatnonzero(dom.signs > 0), 1 + np.flatnonzero(dom.signs < 0)
        A_pm, A_p0, A_0m = T[np.ix_(neg, pos)].T, T[0, pos], T[neg, 0]
        value, _ = solve(A_pm, A_p0, A_0m)
        assert value == pytest.approx(brute_force(A_pm, A_p0, A_0m), rel=1e-12)
        # the min-cost flow with one boundary part is program (34) too
        supply = np.zeros(T.shape[0], dtype=int)
        supply[neg], supply[pos] = 1, -1
        supply[0] = -supply.sum()
        assert solve_flow(T, supply)[0] == pytest.approx(value, rel=1e-9)
