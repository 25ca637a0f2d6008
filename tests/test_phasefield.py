"""Fast checks of the phase-field solver of issue 5 (``validation/phasefield.py``)."""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

import direct
from direct.metric import get_metric
from direct.penalty import domains

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "validation"))
import phasefield as pf  # noqa: E402

J_CROSS = 1.0 / 12.0  # 2 m^3 / 3 with m = 1/2
J_FIG10 = 4.987035  # direct.penalty("fig10", "G", tol=1e-6).value
J_REVERSED = 4 * np.sqrt(2) * np.pi  # smooth circle; the 256-gon gives 17.7693


def test_beta_is_the_one_dimensional_transition_cost():
    t = np.linspace(0.0, 2 * np.pi, 200001)
    f = 2 * np.sqrt(1 - np.cos(t))
    assert np.isclose(np.sum((f[1:] + f[:-1]) / 2 * np.diff(t)), pf.BETA, rtol=1e-8)
    assert np.isclose(pf.BETA, 8 * np.sqrt(2))


@pytest.mark.parametrize("name", ["cross", "fig2", "fig10"])
def test_edge_increments_wind_once_around_each_crossing_point(name):
    """Sum of the exact increments Phi_e around every grid cell: +-2 pi exactly on the cells of crossing points."""
    scene = direct.scenes.get(name)
    dom = domains(scene, direct.find_crossings(scene))[0]
    S = pf._setup(dom, get_metric("G"), 24)
    n1, n2 = S["shape"]
    phi = [np.full((n1, n2), np.nan), np.full((n1, n2), np.nan)]
    for axis in (0, 1):
        sel = S["eaxis"] == axis
        phi[axis][S["epos"][sel, 0], S["epos"][sel, 1]] = S["phi_e"][sel]
    circ = phi[0] + np.roll(phi[1], -1, axis=0) - np.roll(phi[0], -1, axis=1) - phi[1]
    circ = circ[:-1, :-1] if dom.kind != "annulus" else circ
    ok = np.isfinite(circ)
    k = circ[ok] / (2 * np.pi)
    assert np.allclose(k, np.round(k), atol=1e-9)
    windings = np.round(k)
    # one nonzero cell per crossing point of the piece, with the opposite sign of the point (P / 2 pi = -s)
    assert np.count_nonzero(windings) == len(dom.points)
    assert sorted(windings[windings != 0].astype(int)) == sorted((-dom.signs).astype(int))


def test_admissible_scenes_give_zero():
    seg = direct.Scene((direct.Component([[0, 0], [1, 0]], [[0, 0], [1, 0]]),
                        direct.Component([[0, 1], [1, 1]], [[0, 1], [1, 1.5]])))
    circle = direct.scenes.circle_scene(lambda t: np.column_stack([np.cos(t), 0.5 * np.sin(t)]), n=48)
    for scene in (seg, circle):
        res = pf.solve(scene, "G", eps=0.1, n=24)
        assert res.value < 1e-10
        assert res.curves == []


def test_cross_error_grows_like_the_vortex_energy():
    """At fixed eps, halving h adds (2 pi / beta) eps log 2 per signed crossing point (two on cross)."""
    v = {n: pf.solve("cross", "G", eps=0.1, n=n, curves=False).value for n in (32, 64)}
    predicted = 2 * (2 * np.pi / pf.BETA) * 0.1 * np.log(2)
    assert v[64] - v[32] == pytest.approx(predicted, rel=0.05)
    # and the value decreases with eps on a fixed grid, towards J from above
    vals = [pf.solve("cross", "G", eps=e, n=32, curves=False).value for e in (0.2, 0.1, 0.05)]
    assert vals[0] > vals[1] > vals[2] > J_CROSS


def test_cross_curve_runs_from_the_crossing_point_to_the_boundary():
    res = pf.solve("cross", "G", eps=0.05, n=64)
    assert res.escapes >= 1  # the symmetric saddle (curve along the diagonal) was left
    assert len(res.curves) == 1
    c = res.curves[0]
    ends = [c[0], c[-1]]
    assert any(np.allclose(e, [0.5, 0.5]) for e in ends)
    other = [e for e in ends if not np.allclose(e, [0.5, 0.5])][0]
    assert min(other.min(), 1 - other.max()) < 1e-12  # on a side of the square
    assert abs(c[:, 1] - 0.5).max() < 0.02 or abs(c[:, 0] - 0.5).max() < 0.02  # along an axis
    assert res.curve_value == pytest.approx(J_CROSS, rel=1e-6)


def test_circle_pieces():
    """Annulus with a crossing (fig10) and without one (reversed: curves across the annulus)."""
    res = pf.solve("fig10", "G", eps=0.2, n=32)
    assert res.fields[0].domain.kind == "annulus"
    assert len(res.curves) == 2
    ends = np.vstack([np.vstack([c[0], c[-1]]) for c in res.curves]) % res.fields[0].domain.lengths[0]
    for p in ([1.5708, 4.7123], [4.7123, 1.5708]):
        assert np.min(np.abs(ends - p).max(axis=1)) < 1e-3  # ends on both signed points
    assert res.curve_value == pytest.approx(J_FIG10, rel=0.05)
    rev = pf.solve("reversed", "G", eps=0.2, n=32)
    assert len(rev.curves) == 2
    for c in rev.curves:  # each crosses the annulus from one side of the diagonal to the other
        assert abs(abs(c[-1, 1] - c[-1, 0] - (c[0, 1] - c[0, 0])) - rev.fields[0].domain.lengths[0]) < 1e-9
    assert rev.curve_value == pytest.approx(J_REVERSED, rel=0.02)


def test_metric_g_and_cli(capsys):
    res = pf.solve("cross", "g", eps=0.02, n=64)  # the weaker well of g breaks the symmetry only below eps ~ 0.03
    assert res.metric == "g"
    assert res.curve_value == pytest.approx(0.0125, rel=1e-3)  # J^g = 2 m^5 / 5
    pf.main(["cross", "--eps", "0.2", "--n", "16"])
    out = capsys.readouterr().out
    assert "J_eps/beta" in out and "direct" in out and "Newton" in out


def _circle_scenes():
    t = 2 * np.pi * np.arange(64) / 64
    unit = np.column_stack([np.cos(t), np.sin(t)])
    circ = direct.Component(unit, unit, closed=True, name="C")
    seg = direct.Component([[3, -1], [3, 1]], [[0.2, -1.5], [0.5, 1.5]], name="S")
    other = direct.Component(unit + [3, 0], unit * 0.8 + [1.2, 0.1], closed=True, name="D")
    return direct.Scene((circ, seg), name="cyl"), direct.Scene((circ, other), name="tor")


@pytest.mark.parametrize("which, kind, J", [(0, "cylinder", 1.3680267), (1, "torus", 0.7829484)])
def test_cylinder_and_torus_pieces(which, kind, J):
    """A segment moved across a circle, two circles moved onto each other: 2 crossings each.

    ``J`` from ``direct.penalty(scene, "G", tol=1e-6)`` (the torus takes 3 s there).
    """
    scene = _circle_scenes()[which]
    res = pf.solve(scene, "G", eps=0.1, n=48)
    assert kind in [f.domain.kind for f in res.fields]
    assert len(res.curves) == 1
    assert res.curve_value == pytest.approx(J, rel=5e-3)
    assert res.curve_value >= J * (1 - 1e-6)  # an admissible family is never shorter than the oracle's J
    assert res.value > J  # the vortex excess
