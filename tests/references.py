"""Independent reference values of J for two straight segments crossing at any angle.

Not computed with `direct`: for two unit-speed segments crossing at the origin
at angle ``alpha`` the length element is ``rho |dx|`` with
``rho = (x1^2 + x2^2 - 2 x1 x2 cos alpha)^(k/2)`` (``k = 2`` for ``G``,
``k = 4`` for ``g`` with ``p = 2``; in general ``k = q`` for ``G`` with power ``q``
and ``k = 2p`` for ``g``: the deformation is an isometry, so both
metrics are isotropic in the parameters).  ``rho`` is homogeneous of degree
``k``, so the distance from the crossing point is ``|x|^(k+1) f(theta)`` with
the eikonal equation ``(k + 1)^2 f^2 + f'^2 = Q(theta)^2``,
``Q = (1 - cos(alpha) sin(2 theta))^(k/2)`` (shared/NUMERICS.md).  The ODE is
integrated from the cheapest direction ``theta_0`` (where the geodesic is
the straight ray and ``f = Q / (k + 1)``; the singular start uses the
second-order expansion ``f = Q_0/(k+1) + c (theta - theta_0)^2`` over an
interval ``1e-3 sin(alpha)`` wide, inside the valley of width ``~ alpha``) with
``solve_ivp`` at ``rtol = 1e-12`` and an absolute tolerance 1e-12 times the
starting value (the values are tiny for high powers at small angles: about
1e-10 for ``k = 6`` at 0.04 rad, where an absolute 1e-15 cost 3e-5 relative); the distance to the boundary of the
parameter rectangle ``[-a, b] x [-c, d]`` is the minimum of
``r(theta)^(k+1) f(theta)`` over the boundary, and ``J`` counts the two points
of the crossing.  At 60 degrees on the unit square this gives the
NUMERICS.md value 0.2581226580725618 to 1e-13.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar


def _profile(alpha: float, k: int):
    """``f(theta)`` of the distance ``|x|^(k+1) f(theta)`` from the crossing point."""
    ca = np.cos(alpha)

    def Q(t):
        return (1.0 - ca * np.sin(2 * t)) ** (k / 2)

    t0 = np.pi / 4 if ca >= 0 else 3 * np.pi / 4
    q0 = Q(t0)
    h = 1e-4
    B = (Q(t0 + h) - 2 * q0 + Q(t0 - h)) / (2 * h * h)  # Q = q0 + B d^2 + ...
    c = (-2 * (k + 1) * q0 + np.sqrt(4 * (k + 1) ** 2 * q0**2 + 32 * q0 * B)) / 8
    d0 = 1e-3 * min(1.0, abs(np.sin(alpha)))  # the valley around theta_0 is about alpha wide
    branches = {}
    for sgn in (1, -1):
        def rhs(t, f, sgn=sgn):
            return sgn * np.sqrt(np.maximum(Q(t) ** 2 - (k + 1) ** 2 * f**2, 0.0))

        f0 = q0 / (k + 1) + c * d0**2
        branches[sgn] = solve_ivp(rhs, (t0 + sgn * d0, t0 + sgn * np.pi / 2), [f0], rtol=1e-12, atol=1e-12 * f0,
                                  dense_output=True)

    def f(t):
        d = (t - t0 + np.pi / 2) % np.pi - np.pi / 2  # period pi: rho is even
        if abs(d) < d0:
            return q0 / (k + 1) + c * d * d
        return float(branches[1 if d > 0 else -1].sol(t0 + d)[0])

    return f


def crossing_reference(alpha: float, a: float = 1.0, b: float = 1.0, c: float = 1.0, d: float = 1.0,
                       k: int = 2) -> float:
    """``J`` of ``direct.scenes.cross(a, b, c, d, alpha)``: twice the distance from the crossing to the boundary.

    ``k = 2`` for the metric ``G`` (Example 14), ``k = 4`` for ``g`` with ``p = 2``.
    """
    f = _profile(alpha, k)
    lo, hi = np.array([-a, -c]), np.array([b, d])

    def dist(t):
        u = np.array([np.cos(t), np.sin(t)])
        with np.errstate(divide="ignore"):
            r = np.min(np.where(u > 0, hi / u, np.where(u < 0, lo / u, np.inf)))
        return r ** (k + 1) * f(t)

    ts = np.linspace(0, 2 * np.pi, 7201)
    vals = np.array([dist(t) for t in ts])
    best = np.inf
    for i in np.argsort(vals)[:6]:  # polish the best samples (each side of the rectangle is smooth)
        res = minimize_scalar(dist, bounds=(ts[i] - 2 * np.pi / 7200, ts[i] + 2 * np.pi / 7200), method="bounded",
                              options={"xatol": 1e-13})
        best = min(best, res.fun, vals[i])
    return 2.0 * best
