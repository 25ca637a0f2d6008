"""Non-axis-aligned crossings against an independent eikonal-ODE reference (tests/references.py)."""

import numpy as np
import pytest
from references import crossing_reference

import direct


def test_reference_reproduces_the_known_values():
    assert crossing_reference(np.pi / 3) / 2 == pytest.approx(0.2581226580725618, rel=1e-12)  # NUMERICS.md
    assert crossing_reference(np.pi / 2, 0.3, 0.5, 0.4, 0.6) == pytest.approx(2 * 0.3**3 / 3, rel=1e-12)
    assert crossing_reference(np.pi / 2, 0.3, 0.5, 0.4, 0.6, k=4) == pytest.approx(2 * 0.3**5 / 5, rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("metric, k", [("G", 2), ("g", 4)])
def test_any_angle_to_1e6_with_a_covering_estimate(seed, metric, k):
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.15, np.pi - 0.15)
    arms = rng.uniform(0.3, 1.5, 4)
    exact = crossing_reference(alpha, *arms, k=k)
    res = direct.penalty(direct.scenes.cross(*arms, angle=alpha), metric, tol=1e-6)
    err = abs(res.value - exact)
    assert err <= 1e-6 * exact
    assert err <= res.error_estimate


@pytest.mark.parametrize("metric, power, k", [("G", 1.0, 1), ("G", 3.0, 3), ("g", 1.0, 2), ("g", 3.0, 6)])
def test_other_powers_at_small_angles(metric, power, k):
    """Other powers of ``G`` (``|r|^q |dx|``) and ``g`` (``|r|^(2p) |dx|`` for an isometry), at the
    ``--tol 1e-5`` an oracle is called with.  At 0.043 rad and ``k = 6`` the values are about 1e-12:
    the reference once integrated its ODE with an absolute tolerance of 1e-15, 3e-5 relative there,
    and ``direct`` came out 2.9e-5 *below* it (with its polyline, a real curve)."""
    alpha, arms = 0.0429, (1.551, 0.324, 1.517, 0.717)
    exact = crossing_reference(alpha, *arms, k=k)
    res = direct.penalty(direct.scenes.cross(*arms, angle=alpha), metric, power=power, tol=1e-5)
    err = abs(res.value - exact)
    assert err <= 1e-5 * exact
    assert err <= res.error_estimate


@pytest.mark.parametrize("alpha", [0.01, 0.003])
def test_grazing_crossings_reach_the_reference(alpha):
    """A crossing at a small angle: the geodesic runs down a valley of width ~ alpha into a corner and
    turns onto a side just before it; the graded end of the refinement must see the turn."""
    exact = crossing_reference(alpha, 0.5, 0.5, 0.5, 0.5)
    res = direct.penalty(direct.scenes.cross(0.5, 0.5, 0.5, 0.5, angle=alpha))
    err = abs(res.value - exact)
    assert err <= 1e-3 * exact
    assert err <= res.error_estimate


def test_grazing_domains_get_a_second_start_unless_refused():
    """Below a sine of 0.1 the refinement can settle short of the turn into the corner (rounding decides);
    such domains are solved from two grids' routes at every tolerance, and the spread enters the estimate."""
    grazing = direct.scenes.cross(0.5, 0.5, 0.5, 0.5, angle=0.05)
    assert direct.penalty(grazing).settings.get("grazing_second_pass") == 1
    assert "grazing_second_pass" not in direct.penalty(grazing, second_pass=False).settings
    assert "grazing_second_pass" not in direct.penalty(direct.scenes.cross(0.5, 0.5, 0.5, 0.5, angle=0.5)).settings
