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
for the polynomial integrand (``|r|^2`` is quadratic in ``t`` on a piece), or
in closed form when ``rho(s) = s`` (``G`` with ``q = 2``, ``g`` with ``p = 1``).
"""

from __future__ import annotations

import weakref
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable, Literal

import numpy as np

from .checks import is_real_number
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
    #: the norm vanishes on a direction: the grid cannot rank routes (see :class:`direct.DegenerateMetricWarning`)
    degenerate: bool = False
    #: grids uniform in the deformed arclength of each component, where the norm's axes are the stencil's
    #: (see :func:`direct.grid.build_graph`); otherwise uniform in the reference arclength
    deformed_grid: bool = False
    #: the lengths do not depend on the parametrization of M (Prop. 18): :func:`direct.penalty.penalty` may then
    #: compute an unevenly stretched component in its deformed arclength (only a non-degenerate metric)
    reparametrization_invariant: bool = False
    #: lengths do not change under the swap ``(x1, x2) -> (x2, x1)`` of ``M x M``, i.e. ``norm(a, b, (d1, d2)) ==
    #: norm(b, a, (d2, d1))`` (``rho`` depends on ``|r|^2`` only): a circle's curves with itself then come in mirror
    #: pairs of equal length (:func:`direct.penalty.penalty` compares them).  A subclass that changes :meth:`norm`
    #: must set it again.
    swap_symmetric: bool = False

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

    # -- kernels of segment_lengths (overridden by the built-in metrics with shortcuts) -------------
    def _piece_integrals(self, rc: np.ndarray, e: np.ndarray, extra: int, moments: bool):
        """Integrals over straight pieces ``r(s) = rc + s e``, ``s in [-1/2, 1/2]`` (plane vectors as complex).

        Returns ``int rho(|r(s)|^2) ds`` and, with ``moments``, the (3, m) rows
        ``M_k = int rho'(|r(s)|^2) s^k ds`` (k = 0, 1, 2) (a tuple of three
        numbers when ``rho'`` is constant, then ``M_1 = 0``), by Gauss-Legendre
        quadrature with :attr:`n_nodes` ``+ extra`` nodes: exact when
        ``rho(|r(s)|^2)`` is a polynomial in ``s`` (``rho'`` loses the two
        degrees that ``s^2`` adds).
        """
        s, w, ws = _centred_rule(self.n_nodes + extra)
        r = np.multiply.outer(s, e)
        r += rc
        r2 = r.real * r.real
        r2 += r.imag * r.imag
        integral = w @ self.weight(r2)
        return integral, (ws @ self.weight_derivative(r2) if moments else None)

    def _norms(self, X: np.ndarray, d: np.ndarray, gradient: bool):
        """:meth:`norm` (and :meth:`norm_gradient`) with ``X = (phi'(x1), -phi'(x2))`` as a complex (m, 2) array."""
        Xf = X.view(np.float64)
        a, b = Xf[:, :2], -Xf[:, 2:]
        return self.norm(a, b, d), (self.norm_gradient(a, b, d) if gradient else None)

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
    deformed_grid = True  # isotropic in the deformed arclengths
    reparametrization_invariant = True  # h(|phi(x1) - phi(x2)|^2) |(phi'(x1) dx1, phi'(x2) dx2)|
    swap_symmetric = True

    def __post_init__(self):
        if self.h is not None:  # None: a subclass that defines its weight itself (as G does)
            _checked_h(self.h, self.label)

    def weight(self, r2):  # noqa: D102
        return np.sqrt(self.h(r2))

    def norm(self, a, b, d):  # noqa: D102
        return np.sqrt(np.einsum("ij,ij->i", a, a) * d[:, 0] ** 2 + np.einsum("ij,ij->i", b, b) * d[:, 1] ** 2)

    def norm_gradient(self, a, b, d):  # noqa: D102
        n = self.norm(a, b, d)
        g = np.column_stack([np.einsum("ij,ij->i", a, a) * d[:, 0], np.einsum("ij,ij->i", b, b) * d[:, 1]])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n[:, None] > 0, g / n[:, None], 0.0)

    def _norms(self, X, d, gradient):
        if type(self).norm is not GFamily.norm or type(self).norm_gradient is not GFamily.norm_gradient:
            return super()._norms(X, d, gradient)
        w = X.real * X.real
        w += X.imag * X.imag  # |phi'(x1)|^2, |phi'(x2)|^2
        w *= d
        n = np.sqrt(np.einsum("ij,ij->i", w, d))
        return n, (_divide_rows(w, n) if gradient else None)

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
        _checked_power(self.q)

    @property
    def degree(self):  # noqa: D102
        return int(self.q) if float(self.q).is_integer() and int(self.q) % 2 == 0 else None

    @property
    def order(self):  # noqa: D102
        return float(self.q)

    def weight(self, r2):  # noqa: D102
        return r2 if self.q == 2 else r2 ** (self.q / 2)

    def _piece_integrals(self, rc, e, extra, moments):
        if self.q == 2 and type(self).weight is G.weight:
            return _linear_piece_integrals(rc, e, moments)
        return super()._piece_integrals(rc, e, extra, moments)

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
    swap_symmetric = True

    def __post_init__(self):
        _checked_power(self.p)

    @property
    def degree(self):  # noqa: D102
        return 2 * int(self.p) if float(self.p).is_integer() else None

    @property
    def order(self):  # noqa: D102
        return 2.0 * self.p

    def weight(self, r2):  # noqa: D102
        return r2**self.p

    def _piece_integrals(self, rc, e, extra, moments):
        if self.p == 1 and type(self).weight is g.weight:
            return _linear_piece_integrals(rc, e, moments)
        return super()._piece_integrals(rc, e, extra, moments)

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

    def _norms(self, X, d, gradient):
        if type(self).norm is not g.norm or type(self).norm_gradient is not g.norm_gradient:
            return super()._norms(X, d, gradient)
        n = np.hypot(d[:, 0], d[:, 1])
        return n, (_divide_rows(d, n) if gradient else None)

    def describe(self):  # noqa: D102
        return {"metric": "g", "p": self.p}


@dataclass(frozen=True, repr=False)
class Euclid(Metric):
    """The heuristic metric of section 3.1: ``dl = |phi'(x1) dx1 - phi'(x2) dx2|``.

    Lengths are lengths of the curve ``r_phi o gamma`` in the plane; the
    metric is degenerate (zero along the direction where
    ``phi'(x1) dx1 = phi'(x2) dx2``).  In the deformed arclengths ``sigma``
    of two straight segments at angle ``theta`` it is ``dsigma1^2 +
    dsigma2^2 - 2 cos(theta) dsigma1 dsigma2``: its axes are the diagonals
    ``dsigma1 = +-dsigma2``, with eigenvalues ``1 -+ cos(theta)``.
    """

    name = "euclid"
    swap_symmetric = True
    degree = 0
    order = 0.0
    degenerate = True
    deformed_grid = True  # the axes of the norm on the stencil's diagonals
    reparametrization_invariant = True  # |phi'(x1) dx1 - phi'(x2) dx2| (computed in the reference arclength still)

    def weight(self, r2):  # noqa: D102
        return np.ones_like(r2)

    def weight_derivative(self, r2):  # noqa: D102
        return np.zeros_like(r2)

    def _piece_integrals(self, rc, e, extra, moments):
        if type(self).weight is not Euclid.weight or type(self).weight_derivative is not Euclid.weight_derivative:
            return super()._piece_integrals(rc, e, extra, moments)
        return np.ones(len(rc)), ((0.0, 0.0, 0.0) if moments else None)

    def norm(self, a, b, d):  # noqa: D102
        v = a * d[:, :1] - b * d[:, 1:]
        return np.hypot(v[:, 0], v[:, 1])

    def norm_gradient(self, a, b, d):  # noqa: D102
        v = a * d[:, :1] - b * d[:, 1:]
        n = np.hypot(v[:, 0], v[:, 1])
        g = np.column_stack([(a * v).sum(axis=1), -(b * v).sum(axis=1)])
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n[:, None] > 0, g / n[:, None], 0.0)

    def _norms(self, X, d, gradient):
        if type(self).norm is not Euclid.norm or type(self).norm_gradient is not Euclid.norm_gradient:
            return super()._norms(X, d, gradient)
        v = X[:, 0] * d[:, 0]
        v += X[:, 1] * d[:, 1]  # phi'(x1) d1 - phi'(x2) d2
        n = np.hypot(v.real, v.imag)
        if not gradient:
            return n, None
        g = X.real * v.real[:, None]
        g += X.imag * v.imag[:, None]
        return n, _divide_rows(g, n)


def get_metric(metric: "str | Metric" = "G", power: float | None = None) -> Metric:
    """Turn a metric name (and optional power) into a :class:`Metric`.

    Parameters
    ----------
    metric : {"G", "g", "euclid"} or Metric
        The metric; a :class:`Metric` instance is returned as is.
    power : float, optional
        ``q`` of ``G = |y1 - y2|^(2q) Id`` (default 2, Example 14) or ``p`` of
        ``g(s) = s^p`` (default 2): a real number in ``(0, 64]``.  Not
        allowed with ``"euclid"``.

    Returns
    -------
    Metric

    Raises
    ------
    DirectError
        For an unknown metric, or a power that is not a real number in ``(0, 64]``.
    """
    if isinstance(metric, Metric):
        if power is not None:
            raise DirectError("give the power inside the Metric object, not as power=")
        return metric
    if power is not None:
        power = _checked_power(power)
    if metric == "G":
        return G(q=2.0 if power is None else power)
    if metric == "g":
        return g(p=2.0 if power is None else power)
    if metric == "euclid":
        if power is not None:
            raise DirectError("the euclid metric takes no power; use metric 'G' or 'g' with a power")
        return Euclid()
    raise DirectError(f"unknown metric {metric!r}; choose 'G' (Example 14), 'g' (section 3.4.2) or 'euclid'")


#: the largest power accepted: lengths scale as ``|r|`` to twice it (for g), and the quadrature of an integer
#: power takes about that many nodes per piece
_MAX_POWER = 64.0


#: where a GFamily's h is probed (squared distances |r|^2): points where any h of section 3.4.1 is finite and
#: positive in floating point (h(s) = s^50 underflows at 1e-8, an exponential may overflow at 100)
_H_PROBE = np.array([0.0, 0.25, 1.0])


def _checked_h(h, label: str) -> None:
    """A DirectError unless ``h`` maps an array of ``s >= 0`` to finite values, ``h(0) = 0`` and ``h > 0`` beyond.

    Probed at :data:`_H_PROBE` only: it catches a negative ``h``, ``h(0) != 0``
    and an ``h`` that does not take arrays, not every ``h`` outside section 3.4.1.
    """
    if not callable(h):
        raise DirectError(f"GFamily {label!r}: h must be a function of s = |y1 - y2|^2, got {h!r}")
    try:
        with np.errstate(all="ignore"):
            v = np.asarray(h(_H_PROBE.copy()), dtype=float)
    except Exception as err:  # noqa: BLE001  (whatever a user's function raises, said in one message)
        raise DirectError(f"GFamily {label!r}: h must take a numpy array of s >= 0 (vectorized, e.g. with np.exp "
                          f"rather than math.exp); h(array) raised {type(err).__name__}: {err}") from err
    if v.shape != _H_PROBE.shape or not np.all(np.isfinite(v)) or v[0] != 0.0 or not np.all(v[1:] > 0.0):
        raise DirectError(f"GFamily {label!r}: h must be finite, h(0) = 0 and h(s) > 0 for s > 0 (section 3.4.1), "
                          f"one value per s; h({_H_PROBE.tolist()}) = {np.asarray(v).tolist()}")


def _checked_power(power) -> float:
    """``power`` as a float: a real number in ``(0, _MAX_POWER]``, else a DirectError that says what is accepted."""
    if not is_real_number(power):
        raise DirectError(f"power must be a real number, got {power!r} ({type(power).__name__})")
    value = float(power)
    if not (0.0 < value <= _MAX_POWER):
        raise DirectError(f"power must be positive and at most {_MAX_POWER:g} (lengths scale as |r| to about twice "
                          f"the power, beyond floating point for larger ones), got {power!r}")
    return value


@lru_cache(maxsize=None)
def _gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


@lru_cache(maxsize=None)
def _centred_rule(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Legendre rule on ``s in [-1/2, 1/2]``: nodes ``s``, weights ``w`` and ``w s^k`` (k = 0, 1, 2) as (3, n)."""
    t, w = _gauss(n)
    s = t - 0.5
    return s, w, np.vstack([w, w * s, w * s * s])


class _Cells:
    """Per-component tables for :func:`segment_lengths` (components are immutable, so they are cached)."""

    __slots__ = ("params", "inner", "vel", "ring", "length", "closed", "_periodic", "__weakref__")

    def __init__(self, comp):
        self.params = np.ascontiguousarray(comp.params, dtype=float)
        self.inner = self.params[1:-1]  # searchsorted(inner, x, "right") is comp.segment_index(x)
        v, r = comp.velocities, comp.deformed_ring
        self.vel = np.empty(len(v), dtype=complex)  # phi' and the deformed vertices as complex numbers
        self.vel.real, self.vel.imag = v[:, 0], v[:, 1]
        self.ring = np.empty(len(r), dtype=complex)
        self.ring.real, self.ring.imag = r[:, 0], r[:, 1]
        self.length = float(comp.length)
        self.closed = bool(comp.closed)
        self._periodic = {}

    def vertex_params(self, comp, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """:func:`_vertex_params` over ``[min(lo), max(hi)]``, cached by the range of periods it spans."""
        if not self.closed:
            return self.inner
        L, lo, hi = self.length, float(lo.min()), float(hi.max())
        k = (int(np.floor(lo / L)) - 1, int(np.ceil(hi / L)) + 1)
        vp = self._periodic.get(k)
        if vp is None:
            if len(self._periodic) > 64:
                self._periodic.clear()
            vp = self._periodic[k] = _vertex_params(comp, lo, hi)
        return vp


_CELLS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _cells(comp) -> _Cells:
    try:
        return _CELLS[comp]
    except KeyError:
        cells = _CELLS[comp] = _Cells(comp)
        return cells
    except TypeError:  # not weak-referenceable: no cache
        return _Cells(comp)


def _breaks(vertex_params: np.ndarray, u0: np.ndarray, u1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``t in (0, 1)`` where ``u0 + t (u1 - u0)`` passes a vertex parameter.

    Returns the edge index and ``t`` of every such crossing, as flat arrays.
    """
    lo, hi = np.minimum(u0, u1), np.maximum(u0, u1)
    i0 = vertex_params.searchsorted(lo, side="right")
    return _expand_breaks(vertex_params, u0, u1, i0, vertex_params.searchsorted(hi, side="left") - i0)


def _expand_breaks(vertex_params, u0, u1, i0, count) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_breaks` from the first vertex index ``i0`` past each segment's start and the ``count`` it passes."""
    count = np.maximum(count, 0)
    if count.max(initial=0) <= 1:  # one break per segment at most (the usual case): no runs to expand
        edge = count.nonzero()[0]
        vals = vertex_params[i0[edge]]
    else:
        edge = np.repeat(np.arange(len(u0)), count)
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


def _linear_piece_integrals(rc: np.ndarray, e: np.ndarray, moments: bool):
    """:meth:`Metric._piece_integrals` in closed form for ``rho(s) = s``: ``|rc|^2 + |e|^2 / 12``."""
    integral = e.real * e.real
    integral += e.imag * e.imag
    integral /= 12.0
    integral += rc.real * rc.real
    integral += rc.imag * rc.imag
    return integral, ((1.0, 0.0, 1.0 / 12.0) if moments else None)


def _divide_rows(g: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``g / n`` row by row, 0 where ``n = 0`` (a norm's gradient at a zero displacement)."""
    if n.size and n.min() > 0:  # the usual case, without the slower masked division
        return g / n[:, None]
    return np.divide(g, n[:, None], out=np.zeros_like(g), where=n[:, None] > 0)


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
    Each segment is split at the vertex parameters of both components (most
    segments lie in one cell and are a single piece).  On a piece ``phi`` is
    affine in both parameters, so ``r(s) = r_c + s e`` for ``s in [-1/2, 1/2]``
    around the piece's midpoint and the integrand ``rho(|r(s)|^2) ||Q - P||``
    is integrated by Gauss-Legendre quadrature, exactly when ``rho`` is
    polynomial; for ``rho(s) = s`` (``G`` with ``q = 2``) in closed form,
    ``|r_c|^2 + |e|^2 / 12``.  The gradient needs only the moments
    ``int rho'(|r(s)|^2) s^k ds``, ``k <= 2``, of each piece.
    """
    P = np.asarray(P, dtype=float).reshape(-1, 2)
    Q = np.asarray(Q, dtype=float).reshape(-1, 2)
    m = len(P)
    if m == 0:
        return (np.empty(0), np.empty((0, 4))) if gradient else np.empty(0)
    if m > _CHUNK:  # blocks whose temporaries stay small (cache, and no fresh pages from the allocator)
        parts = [_segment_lengths(metric, comps, P[i:i + _CHUNK], Q[i:i + _CHUNK], gradient)
                 for i in range(0, m, _CHUNK)]
        if not gradient:
            return np.concatenate(parts)
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
    return _segment_lengths(metric, comps, P, Q, gradient)


#: segments per block in :func:`segment_lengths` (measured: 2-3x faster than one block of 80k)
_CHUNK = 4096


def _segment_lengths(metric: Metric, comps, P: np.ndarray, Q: np.ndarray, gradient: bool):
    """:func:`segment_lengths` on (m, 2) float arrays, ``m > 0``."""
    cells = (_cells(comps[0]), _cells(comps[1]))
    d = Q - P
    lo, hi = np.minimum(P, Q), np.maximum(P, Q)
    # vertex parameters strictly inside each segment's range, per axis
    found, split = [], None
    for axis, cc in enumerate(cells):
        vp = cc.vertex_params(comps[axis], lo[:, axis], hi[:, axis])
        if vp.size == 0:
            continue
        i0 = vp.searchsorted(lo[:, axis], side="right")
        count = vp.searchsorted(hi[:, axis], side="left") - i0
        found.append((axis, vp, i0, count))
        split = count > 0 if split is None else split | (count > 0)
    if split is None or not split.any():  # every segment lies in one cell: a single piece [0, 1]
        pieces, Pp, dp, tc, h = None, P, d, 0.5, None
        # on an open component that cell is the one right of the segment's start, found above (no vertex lies
        # strictly inside [lo, hi]); a closed one's vertex parameters repeat periodically: located at the midpoint
        cell = {axis: i0 for axis, _, i0, _ in found if not cells[axis].closed}
        cell.update({axis: np.zeros(len(P), dtype=np.intp) for axis, cc in enumerate(cells)
                     if not cc.closed and cc.inner.size == 0})
        mid = None if len(cell) == 2 else P + 0.5 * d
    else:
        pieces, cell = _Pieces(split, found, P, Q), {}
        Pp, dp = P.take(pieces.pe, axis=0), d.take(pieces.pe, axis=0)
        tc, h = 0.5 * (pieces.ta + pieces.tb)[:, None], (pieces.tb - pieces.ta)[:, None]
        mid = Pp + tc * dp
    n = len(Pp)
    # the cell of each piece, located at its midpoint; X = (phi'(x1), -phi'(x2)), r = phi(x1) - phi(x2)
    X = np.empty((n, 2), dtype=complex)
    K = np.empty((n, 2), dtype=np.intp)
    offs = np.empty((n, 2))
    verts = []
    for axis, cc in enumerate(cells):
        if axis in cell:
            k = K[:, axis] = cell[axis]
            cc.params.take(k, out=offs[:, axis])
        elif cc.closed and not (mid[:, axis].min() >= 0.0 and mid[:, axis].max() < cc.length):  # else: no shift
            x = mid[:, axis]
            k = K[:, axis] = cc.inner.searchsorted(np.mod(x, cc.length), side="right")
            offs[:, axis] = cc.params.take(k) + np.floor(x / cc.length) * cc.length  # periodic shift
        else:
            k = K[:, axis] = cc.inner.searchsorted(mid[:, axis], side="right")
            cc.params.take(k, out=offs[:, axis])
        verts.append(cc.ring.take(k))
        cc.vel.take(k, out=X[:, axis])
    np.negative(X[:, 1], out=X[:, 1])
    # offsets of the midpoints from the cells' vertices, from the segments' starts (exact data) rather
    # than from `mid`: near a crossing r is a small difference, best formed from small terms
    np.subtract(Pp, offs, out=offs)
    offs += tc * dp
    rc = verts[0] - verts[1]
    rc += X[:, 0] * offs[:, 0]
    rc += X[:, 1] * offs[:, 1]
    e = X[:, 0] * dp[:, 0]
    e += X[:, 1] * dp[:, 1]
    if h is not None:
        e *= h[:, 0]
    N, dN = metric._norms(X, dp, gradient)
    integral, moments = metric._piece_integrals(rc, e, 1 if gradient else 0, gradient)
    if h is not None:
        integral *= h[:, 0]
    length = integral * N
    if not gradient:
        return length if pieces is None else pieces.total(length)
    # d/dx of rho(|r(x)|^2) is 2 rho' r . X; with the moments M_k = int rho' s^k ds of the piece and
    # t = t_c + h s along the segment, int 2 rho' (r . X) (1 - t or t) ds in closed form
    Xc = X.conj()
    z0 = (rc[:, None] * Xc).real
    z1 = (e[:, None] * Xc).real
    if isinstance(moments, tuple):  # rho' constant: M_1 = 0
        S0, S1 = z0 * moments[0], z1 * moments[2]
    else:
        M0, M1, M2 = moments[:, :, None]
        S0 = z0 * M0 + z1 * M1
        S1 = z0 * M1 + z1 * M2
    T = S0 * tc
    T += S1 if h is None else S1 * h
    hN = (2.0 * N)[:, None] if h is None else 2.0 * N[:, None] * h
    Id = integral[:, None] * dN
    grad = np.empty((n, 4))
    S0 -= T
    S0 *= hN
    np.subtract(S0, Id, out=grad[:, :2])
    T *= hN
    np.add(T, Id, out=grad[:, 2:])
    if pieces is None:
        return length, grad
    pieces.add_jumps(metric, grad, K, X, dp, N, rc, e)
    return pieces.total(length), pieces.total(grad)


class _Pieces:
    """Segments cut at the vertex lines: the whole ones (one piece each) first, then the others' pieces in order.

    Attributes ``pe``, ``ta``, ``tb``: segment and parameter interval ``[ta, tb]`` of each piece.
    """

    def __init__(self, split, found, P, Q):
        self.m = len(split)
        self.whole = whole = (~split).nonzero()[0]
        self.many = many = split.nonzero()[0]
        nw, nm = len(whole), len(many)
        self._where = None
        self._pairs = self._one_break(found, P, Q)
        if self._pairs:
            return
        # the split segments' break points sorted by (segment, t), keys segment + i t; the starts, the
        # breaks of each axis and the ends come as four sorted runs that a stable sort merges fast
        breaks = [_expand_breaks(vp, P[:, axis], Q[:, axis], i0, count) for axis, vp, i0, count in found]
        key = np.empty(2 * nm + sum(len(e) for e, _ in breaks), dtype=complex)
        key.real = np.concatenate([many] + [e for e, _ in breaks] + [many])
        key.imag = np.concatenate([np.zeros(nm)] + [t for _, t in breaks] + [np.ones(nm)])
        key = key[np.argsort(key, kind="stable")]
        # consecutive values bound the pieces, except the empty ones (a corner, where both axes break
        # at once) and the steps from a segment's end (t = 1) to the next one's start (t = 0)
        t = key.imag
        cut = (t[1:] > t[:-1]).nonzero()[0]
        pe = key.real[cut].astype(np.intp)
        same = pe[1:] == pe[:-1]
        self.next = same.nonzero()[0] + nw  # pieces followed by another of their segment, at a vertex line
        starts = np.concatenate([[0], (~same).nonzero()[0] + 1])
        self.starts = starts if len(starts) == nm else None  # each split segment keeps a piece
        self.ta = np.concatenate([np.zeros(nw), t[cut]])
        self.tb = np.concatenate([np.ones(nw), t[cut + 1]])
        self.pe = np.concatenate([whole, pe])

    def _one_break(self, found, P, Q) -> bool:
        """The pieces when every split segment crosses one vertex line, strictly inside: ``[0, t]`` and ``[t, 1]``.

        The same arrays as the general construction (the same ``t``, from
        :func:`_expand_breaks`), without its sort: three calls in four of
        :func:`segment_lengths` during a refinement are of this kind
        (interval scenes at the default ``tol``).  False, and nothing set,
        otherwise.
        """
        many, nw, nm = self.many, len(self.whole), len(self.many)
        total = None
        for _, _, _, count in found:  # a count of -1 (a segment on a line, of no extent along it) passes none
            total = np.maximum(count, 0) if total is None else total + np.maximum(count, 0)
        if total.max() != 1:
            return False
        t = np.empty(nm)
        for axis, vp, i0, count in found:
            e, te = _expand_breaks(vp, P[:, axis], Q[:, axis], i0, count)
            t[many.searchsorted(e)] = te
        if not (t.min() > 0.0 and t.max() < 1.0):  # a break at an end: the general construction drops its piece
            return False
        ta, tb = np.zeros(nw + 2 * nm), np.ones(nw + 2 * nm)
        ta[nw + 1::2] = t
        tb[nw::2] = t
        self.ta, self.tb = ta, tb
        self.pe = np.concatenate([self.whole, np.repeat(many, 2)])
        self.starts = 2 * np.arange(nm)
        self.next = self.starts + nw
        return True

    def total(self, values: np.ndarray) -> np.ndarray:
        """Sum piece values per segment."""
        if self.starts is None:
            out = np.zeros((self.m,) + values.shape[1:])
            np.add.at(out, self.pe, values)
            return out
        nw = len(self.whole)
        if self._pairs:  # two pieces per split segment (_one_break): the same sums, without reduceat and take
            out = np.empty((self.m,) + values.shape[1:])
            out[self.whole] = values[:nw]
            out[self.many] = values[nw::2] + values[nw + 1::2]
            return out
        if self._where is None:  # row of each segment in [whole pieces, sums of the others]
            self._where = np.empty(self.m, dtype=np.intp)
            self._where[self.whole] = np.arange(nw)
            self._where[self.many] = np.arange(nw, self.m)
        stacked = np.concatenate([values[:nw], np.add.reduceat(values[nw:], self.starts, axis=0)])
        return stacked.take(self._where, axis=0)

    def add_jumps(self, metric, grad, K, X, dp, N, rc, e) -> None:
        """Jumps of the integrand where a piece ends on a vertex line, times the motion of that crossing."""
        p = self.next
        if not p.size:
            return
        q = p + 1
        rk = e[p]
        rk *= 0.5
        rk += rc[p]  # r at the end of piece p, on its own cell
        rhok = metric.weight(rk.real * rk.real + rk.imag * rk.imag)
        dpp = dp.take(p, axis=0)
        # through the corner, when both lines are crossed at once: first x1's line, then x2's
        corner = np.empty((len(p), 2), dtype=complex)
        X[:, 0].take(q, out=corner[:, 0])
        X[:, 1].take(p, out=corner[:, 1])
        n_mid = metric._norms(corner, dpp, False)[0]
        jump = np.empty((len(p), 2))
        np.subtract(N.take(p), n_mid, out=jump[:, 0])  # rho (N_before - N_after) on the line crossed
        np.subtract(n_mid, N.take(q), out=jump[:, 1])
        jump *= rhok[:, None]
        jump *= K.take(p, axis=0) != K.take(q, axis=0)  # only on the lines crossed
        # the crossing at t_k = (vertex - P) / d moves with the ends: dt_k/dP = (t_k - 1) / d, dt_k/dQ = -t_k / d
        jump = np.divide(jump, dpp, out=np.zeros_like(jump), where=dpp != 0)
        tk = self.tb.take(p)[:, None]
        grad[p, :2] += jump * (tk - 1.0)
        grad[p, 2:] -= jump * tk
