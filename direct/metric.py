r"""Metrics on M x M and the exact length of straight segments in it.

Every metric of the paper has, on each cell ``S_k x S_l`` (a segment of one
component times a segment of the other, where ``phi`` is affine on both), the
form

.. math::

    dl = \rho(|r_\varphi(x)|^2)\, \|dx\|_{k l},

a scalar weight of ``|r|^2 = |phi(x1) - phi(x2)|^2`` times a norm that is
constant on the cell.  With ``a = phi'(x1)``, ``b = phi'(x2)`` (per unit of
reference arclength):

=============  ==============================  =========================================
name           weight :math:`\rho(s)`           norm :math:`\|dx\|`
=============  ==============================  =========================================
``"G"``        :math:`s^{q/2}` (q = 2)           :math:`\sqrt{|a|^2 dx_1^2 + |b|^2 dx_2^2}`
``"g"``        :math:`s^p` (p = 2)               :math:`\sqrt{dx_1^2 + dx_2^2}`
``"euclid"``   :math:`1`                         :math:`|a\, dx_1 - b\, dx_2|`
=============  ==============================  =========================================

``"G"`` is the metric ``G(y1, y2) = |y1 - y2|^{2q} Id`` of section 3.4.1 pulled
back by ``phi x phi`` (Example 14 is ``q = 2``, the default, invariant under
reparametrization, Prop. 18); :class:`GFamily` takes any ``G = h(|y1 - y2|^2) Id``.
``"g"`` is the non-degenerate family of section 3.4.2, ``L^g = \int g(|r|^2) ds``
with ``g(s) = s^p`` and ``ds`` the arclength of M x M in reference arclength.
``"euclid"`` is the heuristic metric ``|phi'(x1) dx1 - phi'(x2) dx2|`` of section 3.1.

Edge weight rule: the length of a straight segment ``P -> Q`` of a pair domain
is the integral of ``rho(|r(P + t (Q - P))|^2) ||Q - P||`` over ``t in [0, 1]``,
split where the segment crosses a vertex parameter of either component, each
piece integrated by Gauss-Legendre quadrature with enough nodes to be exact
for the polynomial integrand (``|r|^2`` is quadratic in ``t`` on a piece).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable, Literal

import numpy as np

from .errors import DirectError

__all__ = ["Metric", "GFamily", "G", "g", "Euclid", "get_metric", "segment_lengths", "MetricName"]

MetricName = Literal["G", "g", "euclid"]


class Metric(ABC):
    """A metric on M x M of the form ``rho(|r_phi|^2) ||dx||`` (see the module docstring)."""

    #: short name used in summaries and JSON
    name: str = ""
    #: polynomial degree in ``t`` of ``rho(|r(t)|^2)`` on a straight piece, or None if not polynomial
    degree: int | None = None
    #: weight of a straight segment near a crossing grows like ``|x|^order`` (used for error estimates)
    order: float = 0.0

    @abstractmethod
    def weight(self, r2: np.ndarray) -> np.ndarray:
        """The weight ``rho`` as a function of ``|r_phi|^2`` (squared length units)."""

    @abstractmethod
    def norm(self, a: np.ndarray, b: np.ndarray, d: np.ndarray) -> np.ndarray:
        """The norm of the parameter displacement ``d`` given ``a = phi'(x1)``, ``b = phi'(x2)``.

        Parameters
        ----------
        a, b : (m, 2) ndarray
            Velocities of the deformation on the two segments of the cell.
        d : (m, 2) ndarray
            Displacements in parameter space (reference arclength).
        """

    def weight_derivative(self, r2: np.ndarray) -> np.ndarray:
        """``d rho / d(|r|^2)``, for gradients of lengths."""
        h = 1e-7 * np.maximum(r2, 1e-300)
        return (self.weight(r2 + h) - self.weight(np.maximum(r2 - h, 0.0))) / (r2 + h - np.maximum(r2 - h, 0.0))

    def norm_gradient(self, a: np.ndarray, b: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Gradient of :meth:`norm` with respect to ``d``, shape (m, 2)."""
        n = self.norm(a, b, d)
        with np.errstate(invalid="ignore", divide="ignore"):
            out = np.empty_like(d)
            for k in (0, 1):
                e = np.zeros_like(d)
                e[:, k] = 1e-7 * np.maximum(np.abs(d).max(axis=1), 1e-300)
                out[:, k] = (self.norm(a, b, d + e) - self.norm(a, b, d - e)) / (2 * e[:, k])
        return np.where(np.isfinite(out), out, 0.0) * (n > 0)[:, None]

    @property
    def n_nodes(self) -> int:
        """Gauss-Legendre nodes per piece: exact when the integrand is polynomial, else 12."""
        return 12 if self.degree is None else self.degree // 2 + 1

    def describe(self) -> dict:
        """Settings that define the metric, for summaries and JSON output."""
        return {"metric": self.name}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.describe().items() if k != "metric")
        return f"{type(self).__name__}({args})"


@dataclass(frozen=True, repr=False)
class GFamily(Metric):
    """``G(y1, y2) = h(|y1 - y2|^2) Id`` (section 3.4.1): ``dl = sqrt(h(|r|^2)) |(a dx1, b dx2)|``.

    Parameters
    ----------
    h : callable
        ``h(s) >= 0`` with ``h(s) = 0`` only at ``s = 0`` (vectorized over ``s``).
    label : str
        Name shown in summaries.

    Notes
    -----
    A general ``h`` is integrated with 12-node Gauss-Legendre quadrature per
    piece, which is not exact; :class:`G` (``h(s) = s^q``) is exact for even ``q``.
    """

    h: Callable[[np.ndarray], np.ndarray]
    label: str = "h"

    name = "G"

    def weight(self, r2):  # noqa: D102
        return np.sqrt(self.h(r2))

    def norm(self, a, b, d):  # noqa: D102
        return np.sqrt(np.einsum("ij,ij->i", a, a) * d[:, 0] ** 2 + np.einsum("ij,ij->i", b, b) * d[:, 1] ** 2)

    def norm_gradient(self, a, b, d):  # noqa: D102
        n = self.norm(a, b, d)
        g = np.column_stack([np.einsum("ij,ij->i", a, a) * d[:, 0], np.einsum("ij,ij->i", b, b) * d[:, 1]])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n[:, None] > 0, g / n[:, None], 0.0)

    def describe(self):  # noqa: D102
        return {"metric": "G", "h": self.label}


@dataclass(frozen=True, repr=False)
class G(GFamily):
    """The paper's metric ``G(y1, y2) = |y1 - y2|^(2 q) Id``; Example 14 is ``q = 2`` (the default).

    Parameters
    ----------
    q : float, default 2
        Exponent: the length element is ``|r|^q |(phi'(x1) dx1, phi'(x2) dx2)|``.
    """

    h: Callable | None = None
    label: str = ""
    q: float = 2.0

    def __post_init__(self):
        if not (self.q > 0 and np.isfinite(self.q)):
            raise DirectError(f"G metric: the exponent q must be positive and finite, got {self.q!r}")

    @property
    def degree(self):  # noqa: D102
        return int(self.q) if float(self.q).is_integer() and int(self.q) % 2 == 0 else None

    @property
    def order(self):  # noqa: D102
        return float(self.q)

    def weight(self, r2):  # noqa: D102
        return r2 if self.q == 2 else r2 ** (self.q / 2)

    def weight_derivative(self, r2):  # noqa: D102
        if self.q == 2:
            return np.ones_like(r2)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = (self.q / 2) * r2 ** (self.q / 2 - 1)
        return np.where(np.isfinite(out), out, 0.0)

    def describe(self):  # noqa: D102
        return {"metric": "G", "q": self.q}


@dataclass(frozen=True, repr=False)
class g(Metric):  # noqa: N801  (the paper's name)
    """The non-degenerate family of section 3.4.2: ``L^g = int g(|r|^2) ds`` with ``g(s) = s^p``.

    ``ds`` is the Euclidean arclength of M x M in reference arclength, so
    ``J^g`` depends on the parametrization of M (section 3.4.4).

    Parameters
    ----------
    p : float, default 2
        Exponent of ``g(s) = s^p`` (``p > 0``).
    """

    p: float = 2.0

    name = "g"

    def __post_init__(self):
        if not (self.p > 0 and np.isfinite(self.p)):
            raise DirectError(f"g metric: the power p must be positive and finite, got {self.p!r}")

    @property
    def degree(self):  # noqa: D102
        return 2 * int(self.p) if float(self.p).is_integer() else None

    @property
    def order(self):  # noqa: D102
        return 2.0 * self.p

    def weight(self, r2):  # noqa: D102
        return r2**self.p

    def weight_derivative(self, r2):  # noqa: D102
        with np.errstate(divide="ignore", invalid="ignore"):
            out = self.p * r2 ** (self.p - 1)
        return np.where(np.isfinite(out), out, 0.0)

    def norm(self, a, b, d):  # noqa: D102
        return np.hypot(d[:, 0], d[:, 1])

    def norm_gradient(self, a, b, d):  # noqa: D102
        n = self.norm(a, b, d)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n[:, None] > 0, d / n[:, None], 0.0)

    def describe(self):  # noqa: D102
        return {"metric": "g", "p": self.p}


@dataclass(frozen=True, repr=False)
class Euclid(Metric):
    """The heuristic metric of section 3.1: ``dl = |phi'(x1) dx1 - phi'(x2) dx2|``.

    Lengths are lengths of the curve ``r_phi o gamma`` in the plane; the
    metric is degenerate (zero along the diagonal direction where
    ``phi'(x1) = phi'(x2)``).
    """

    name = "euclid"
    degree = 0
    order = 0.0

    def weight(self, r2):  # noqa: D102
        return np.ones_like(r2)

    def weight_derivative(self, r2):  # noqa: D102
        return np.zeros_like(r2)

    def norm(self, a, b, d):  # noqa: D102
        v = a * d[:, :1] - b * d[:, 1:]
        return np.hypot(v[:, 0], v[:, 1])

    def norm_gradient(self, a, b, d):  # noqa: D102
        v = a * d[:, :1] - b * d[:, 1:]
        n = np.hypot(v[:, 0], v[:, 1])
        g = np.column_stack([(a * v).sum(axis=1), -(b * v).sum(axis=1)])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n[:, None] > 0, g / n[:, None], 0.0)


def get_metric(metric: "str | Metric" = "G", power: float | None = None) -> Metric:
    """Turn a metric name (and optional power) into a :class:`Metric`.

    Parameters
    ----------
    metric : {"G", "g", "euclid"} or Metric
        The metric; a :class:`Metric` instance is returned as is.
    power : float, optional
        ``q`` of ``G = |y1 - y2|^(2q) Id`` (default 2, Example 14) or ``p`` of
        ``g(s) = s^p`` (default 2).  Not allowed with ``"euclid"``.

    Returns
    -------
    Metric
    """
    if isinstance(metric, Metric):
        if power is not None:
            raise DirectError("give the power inside the Metric object, not as power=")
        return metric
    if metric == "G":
        return G(q=2.0 if power is None else float(power))
    if metric == "g":
        return g(p=2.0 if power is None else float(power))
    if metric == "euclid":
        if power is not None:
            raise DirectError("the euclid metric takes no power; use metric 'G' or 'g' with a power")
        return Euclid()
    raise DirectError(f"unknown metric {metric!r}; choose 'G' (Example 14), 'g' (section 3.4.2) or 'euclid'")


@lru_cache(maxsize=None)
def _gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def _breaks(vertex_params: np.ndarray, u0: np.ndarray, u1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``t in (0, 1)`` where ``u0 + t (u1 - u0)`` passes a vertex parameter.

    Returns the edge index and ``t`` of every such crossing, as flat arrays.
    """
    lo, hi = np.minimum(u0, u1), np.maximum(u0, u1)
    i0 = np.searchsorted(vertex_params, lo, side="right")
    i1 = np.searchsorted(vertex_params, hi, side="left")
    count = np.maximum(i1 - i0, 0)
    edge = np.repeat(np.arange(len(u0)), count)
    if edge.size == 0:
        return edge, np.empty(0)
    start = np.repeat(np.cumsum(count) - count, count)
    vals = vertex_params[np.repeat(i0, count) + np.arange(edge.size) - start]
    return edge, (vals - u0[edge]) / (u1[edge] - u0[edge])


def _vertex_params(comp, lo: float, hi: float) -> np.ndarray:
    """Vertex parameters of a component, repeated periodically over ``[lo, hi]`` when closed."""
    if not comp.closed:
        return comp.params[1:-1]
    L = comp.length
    k0, k1 = int(np.floor(lo / L)) - 1, int(np.ceil(hi / L)) + 1
    return (comp.params[:-1][None, :] + L * np.arange(k0, k1 + 1)[:, None]).ravel()


def _locate(comp, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment index and parameter reduced to the component's range."""
    if comp.closed:
        s = np.mod(s, comp.length)
    return comp.segment_index(s), s


def segment_lengths(metric: Metric, comps, P: np.ndarray, Q: np.ndarray, gradient: bool = False):
    """Exact metric lengths of straight segments ``P -> Q`` in a pair domain ``I_i x I_j``.

    Parameters
    ----------
    metric : Metric
        The metric on M x M.
    comps : tuple of two Component
        The components ``(M_i, M_j)`` whose product is the domain.
    P, Q : (m, 2) array_like of float
        End points in parameters ``(x1, x2)`` (reference arclength); for a
        closed component the parameter may leave ``[0, length]`` and is read
        modulo the length.
    gradient : bool, default False
        Also return the gradient of each length with respect to ``(P1, P2, Q1, Q2)``.

    Returns
    -------
    lengths : (m,) ndarray of float
        The lengths (length units raised to the metric's homogeneity: for
        ``G`` with ``q = 2``, length^3).
    grad : (m, 4) ndarray of float
        Only with ``gradient=True``: the exact derivative of the piecewise
        formula (Leibniz rule: integrals of the derivative on each piece, plus
        the jump of the integrand at each vertex line times the motion of the
        crossing point).

    Notes
    -----
    Each segment is split at the vertex parameters of both components; on
    each piece the integrand ``rho(|r(t)|^2) ||Q - P||`` is integrated by
    Gauss-Legendre quadrature, exactly when ``rho`` is polynomial.
    """
    P = np.asarray(P, dtype=float).reshape(-1, 2)
    Q = np.asarray(Q, dtype=float).reshape(-1, 2)
    m = len(P)
    ci, cj = comps
    if m == 0:
        return (np.empty(0), np.empty((0, 4))) if gradient else np.empty(0)
    es, ts = [], []
    for axis, comp in enumerate((ci, cj)):
        u0, u1 = P[:, axis], Q[:, axis]
        vp = _vertex_params(comp, float(min(u0.min(), u1.min())), float(max(u0.max(), u1.max())))
        e, t = _breaks(vp, u0, u1)
        es.append(e)
        ts.append(t)
    split = np.zeros(m, dtype=bool)
    split[np.concatenate(es)] = True
    whole = np.flatnonzero(~split)  # most segments lie in one cell: a single piece [0, 1]
    many = np.flatnonzero(split)
    # the others: sort their break points and cut them into consecutive pieces
    edge = np.concatenate([many, many] + es)
    t = np.concatenate([np.zeros(len(many)), np.ones(len(many))] + ts)
    order = np.lexsort((t, edge))
    edge, t = edge[order], t[order]
    same = edge[1:] == edge[:-1]
    ta, tb, pe = t[:-1][same], t[1:][same], edge[:-1][same]
    keep = tb > ta
    ta = np.concatenate([np.zeros(len(whole)), ta[keep]])
    tb = np.concatenate([np.ones(len(whole)), tb[keep]])
    pe = np.concatenate([whole, pe[keep]])
    d = Q[pe] - P[pe]
    mid = P[pe] + 0.5 * (ta + tb)[:, None] * d
    k1, _ = _locate(ci, mid[:, 0])
    k2, _ = _locate(cj, mid[:, 1])
    a, b = ci.velocities[k1], cj.velocities[k2]
    # phi on the piece's own segments (no re-location at the nodes), periodic shift for circles
    shift1 = np.floor(mid[:, 0] / ci.length) * ci.length if ci.closed else 0.0
    shift2 = np.floor(mid[:, 1] / cj.length) * cj.length if cj.closed else 0.0
    base1 = ci.deformed_ring[k1] - (ci.params[k1] + shift1)[:, None] * a
    base2 = cj.deformed_ring[k2] - (cj.params[k2] + shift2)[:, None] * b
    nodes, weights = _gauss(metric.n_nodes + (1 if gradient else 0))
    tq = ta[:, None] + (tb - ta)[:, None] * nodes[None, :]  # (pieces, nodes)
    x1 = P[pe, 0][:, None] + tq * d[:, 0][:, None]
    x2 = P[pe, 1][:, None] + tq * d[:, 1][:, None]
    r = (base1[:, None, :] + x1[..., None] * a[:, None, :]) - (base2[:, None, :] + x2[..., None] * b[:, None, :])
    r2 = np.einsum("pqk,pqk->pq", r, r)
    rho = metric.weight(r2)
    N = metric.norm(a, b, d)
    dt = tb - ta
    integral = (rho * weights[None, :]).sum(axis=1) * dt
    lengths = np.bincount(pe, weights=integral * N, minlength=m)
    if not gradient:
        return lengths
    # d/dx of rho(|r(x)|^2): r depends on x1 through a and on x2 through -b
    drho = metric.weight_derivative(r2)
    gx1 = 2 * drho * np.einsum("pqk,pk->pq", r, a)
    gx2 = -2 * drho * np.einsum("pqk,pk->pq", r, b)
    w = weights[None, :] * dt[:, None]
    one_minus = 1.0 - tq
    dN = metric.norm_gradient(a, b, d)
    Irho = integral
    g = np.empty((len(pe), 4))
    g[:, 0] = (w * one_minus * gx1).sum(axis=1) * N - Irho * dN[:, 0]
    g[:, 1] = (w * one_minus * gx2).sum(axis=1) * N - Irho * dN[:, 1]
    g[:, 2] = (w * tq * gx1).sum(axis=1) * N + Irho * dN[:, 0]
    g[:, 3] = (w * tq * gx2).sum(axis=1) * N + Irho * dN[:, 1]
    # jumps of the integrand where a piece ends on a vertex line, times the motion of that crossing
    nxt = (pe[1:] == pe[:-1]) & (np.abs(tb[:-1] - ta[1:]) <= 1e-15)
    p = np.flatnonzero(nxt)
    if p.size:
        tk = tb[p]
        xk = P[pe[p]] + tk[:, None] * d[p]
        rk = (base1[p] + xk[:, :1] * a[p]) - (base2[p] + xk[:, 1:] * b[p])
        rhok = metric.weight((rk * rk).sum(axis=1))
        ch1 = k1[p] != k1[p + 1]
        ch2 = k2[p] != k2[p + 1]
        n_mid = metric.norm(a[p + 1], b[p], d[p])  # through the corner: first x1's line, then x2's
        j1 = np.where(ch1, rhok * (N[p] - np.where(ch2, n_mid, N[p + 1])), 0.0)
        j2 = np.where(ch2, rhok * (np.where(ch1, n_mid, N[p]) - N[p + 1]), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            for axis, jump in ((0, j1), (1, j2)):
                da = d[p, axis]
                okk = (jump != 0) & (da != 0)
                g[p[okk], axis] += jump[okk] * (tk[okk] - 1.0) / da[okk]
                g[p[okk], 2 + axis] += jump[okk] * (-tk[okk]) / da[okk]
    grad = np.zeros((m, 4))
    np.add.at(grad, pe, g)
    return lengths, grad
