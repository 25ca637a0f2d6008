r"""The assignment program (34) of section 5.1.1.

With ``n+`` positive points ``y_i^+`` and ``n-`` negative points ``y_j^-``,
distances ``A_ij`` between them, ``A_i0``, ``A_0j`` to the boundary and
``A_00 = 0``,

.. math::

    J(\varphi) = \min_{v \in V} \sum_{i=0..n^+,\ j=0..n^-} v_{ij} A_{ij}  \qquad (34)

over 0/1 matrices whose rows ``i >= 1`` and columns ``j >= 1`` sum to one
(eqs. (35), (36)).  The paper enumerates ``V``; here it is the square
``(n+ + n-)`` assignment problem

.. math::

    C = \begin{pmatrix} A_{+-} & \mathrm{diag}(A_{+0}) \\
                        \mathrm{diag}(A_{0-}) & 0 \end{pmatrix}

(off-diagonal entries of the two diagonal blocks forbidden), solved in
polynomial time by :func:`scipy.optimize.linear_sum_assignment`.
:func:`brute_force` enumerates ``V`` as the paper does, for cross-checks.
"""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np
from scipy.optimize import linear_sum_assignment

from .errors import DirectError

__all__ = ["solve", "brute_force", "solve_flow", "solve_torus"]


def solve(A_pm: np.ndarray, A_p0: np.ndarray, A_0m: np.ndarray) -> tuple[float, list[tuple[int | None, int | None]]]:
    """Solve program (34) by a linear assignment.

    Parameters
    ----------
    A_pm : (n+, n-) array_like of float
        Distances between positive and negative points.
    A_p0 : (n+,) array_like of float
        Distances from the positive points to the boundary.
    A_0m : (n-,) array_like of float
        Distances from the negative points to the boundary.

    Returns
    -------
    value : float
        The minimum of (34).
    pairs : list of (int or None, int or None)
        ``(i, j)``: positive point ``i`` joined to negative point ``j``;
        ``None`` stands for the boundary.

    Examples
    --------
    >>> solve([[1.0]], [0.4], [0.7])
    (1.0, [(0, 0)])
    >>> solve([[1.0]], [0.4], [0.5])
    (0.9, [(0, None), (None, 0)])
    """
    A_pm = np.asarray(A_pm, dtype=float).reshape(len(A_p0), len(A_0m))
    A_p0 = np.asarray(A_p0, dtype=float)
    A_0m = np.asarray(A_0m, dtype=float)
    npos, nneg = len(A_p0), len(A_0m)
    n = npos + nneg
    if n == 0:
        return 0.0, []
    big = 1.0 + 2.0 * (np.abs(A_p0).sum() + np.abs(A_0m).sum())  # dearer than any feasible assignment
    C = np.zeros((n, n))
    C[:npos, :nneg] = np.minimum(A_pm, big)
    C[:npos, nneg:] = big
    C[np.arange(npos), nneg + np.arange(npos)] = A_p0
    C[npos:, :nneg] = big
    C[npos + np.arange(nneg), np.arange(nneg)] = A_0m
    rows, cols = linear_sum_assignment(C)
    pairs: list[tuple[int | None, int | None]] = []
    value = 0.0
    for r, c in zip(rows, cols):
        if r < npos and c < nneg:
            pairs.append((int(r), int(c)))
            value += A_pm[r, c]
        elif r < npos:
            pairs.append((int(r), None))
            value += A_p0[r]
        elif c < nneg:
            pairs.append((None, int(c)))
            value += A_0m[c]
    return float(value), pairs


def brute_force(A_pm: np.ndarray, A_p0: np.ndarray, A_0m: np.ndarray) -> float:
    """Program (34) by enumeration of ``V``, as in the paper (exponential; small cases only).

    Parameters
    ----------
    A_pm, A_p0, A_0m : array_like
        As in :func:`solve`.

    Returns
    -------
    float
        The minimum of (34).
    """
    A_pm = np.asarray(A_pm, dtype=float).reshape(len(A_p0), len(A_0m))
    npos, nneg = len(A_p0), len(A_0m)
    best = np.inf
    # choose which positive points are matched, and to which negative points (injective)
    for k in range(min(npos, nneg) + 1):
        for plus in itertools.combinations(range(npos), k):
            for minus in itertools.permutations(range(nneg), k):
                cost = sum(A_pm[i, j] for i, j in zip(plus, minus))
                cost += sum(A_p0[i] for i in range(npos) if i not in plus)
                cost += sum(A_0m[j] for j in range(nneg) if j not in minus)
                best = min(best, cost)
    return float(best)


def solve_flow(cost: np.ndarray, supply: np.ndarray) -> tuple[float, list[tuple[int, int, int]]]:
    """Program (34) with prescribed boundary fluxes: a min-cost flow between terminals.

    For M with circles the curves ``gamma`` may have to cross a domain from
    one boundary part to another a prescribed number of times (eq. (10) and
    the flux conditions of eq. (6)); see :mod:`direct.penalty`.  Each
    terminal ``u`` (a boundary part or a crossing point) emits ``supply[u]``
    curves net (negative: receives); a curve from ``u`` to ``v`` costs
    ``cost[u, v]``.  The node-arc incidence matrix is totally unimodular, so
    the linear program has an integral optimal vertex, found by the HiGHS
    dual simplex.  With a single boundary part and ``supply = n+ - n-`` on it
    this is exactly program (34).

    Parameters
    ----------
    cost : (n, n) array_like of float
        ``cost[u, v]``: length of the best curve from ``u`` to ``v`` (inf: none).
    supply : (n,) array_like of int
        Net number of curves starting at each terminal; sums to zero.

    Returns
    -------
    value : float
        The least total length.
    arcs : list of (u, v, count)
        ``count`` curves run from ``u`` to ``v``.

    Raises
    ------
    DirectError
        If no family of curves satisfies the supplies.

    Examples
    --------
    Terminal 0 is the boundary, 1 a negative point, 2 a positive point:

    >>> solve_flow([[0, 1.0, 0.4], [1.0, 0, 0.7], [0.4, 0.7, 0]], [0, 1, -1])
    (0.7, [(1, 2, 1)])
    >>> solve_flow([[0, 0.2, 0.4], [0.2, 0, 0.7], [0.4, 0.7, 0]], [0, 1, -1])
    (0.6000000000000001, [(0, 2, 1), (1, 0, 1)])
    """
    from scipy.optimize import linprog

    C = np.asarray(cost, dtype=float)
    b = np.asarray(supply, dtype=float)
    n = len(b)
    if b.sum() != 0:
        raise DirectError(f"supplies must add up to zero, got {b.tolist()}")
    if not np.any(b):
        return 0.0, []
    u, v = np.nonzero(~np.eye(n, dtype=bool) & np.isfinite(C))
    if len(u) == 0:
        raise DirectError("no family of curves meets the boundary conditions: no terminal reaches another")
    A = np.zeros((n, len(u)))
    A[u, np.arange(len(u))] = 1.0
    A[v, np.arange(len(u))] -= 1.0
    c = C[u, v]

    def run(cols, scale):
        return linprog(c[cols] / scale, A_eq=A[:, cols], b_eq=b, bounds=(0, None), method="highs-ds",
                       options=_HIGHS_LP)

    flow = _two_stage(run, c, "no family of curves meets the boundary conditions")
    arcs = [(int(u[k]), int(v[k]), int(flow[k])) for k in np.flatnonzero(flow)]
    return float(c @ flow), arcs


#: HiGHS's feasibility tolerances for :func:`solve_flow`, on costs scaled to at most 1 (its defaults are 1e-7)
_HIGHS_LP = {"dual_feasibility_tolerance": 1e-10, "primal_feasibility_tolerance": 1e-10}


def _two_stage(run, c: np.ndarray, infeasible: str, once: bool = False) -> np.ndarray:
    """Solve a program of nonnegative costs ``c`` with HiGHS, robustly to their scale (:func:`solve_flow`, torus).

    HiGHS's tolerances are absolute: on raw costs of 1e-6 (a scene a thousand
    times smaller than the unit: ``G``'s lengths scale as the cube) every
    feasible choice looked optimal, and ``fig10`` came out twice its value
    with an estimate of 1e-12.  ``run(cols, scale)`` solves the program on
    the columns ``cols`` with costs ``c[cols] / scale`` (a scipy result);
    ``infeasible`` is the error message when it finds no solution.  The
    result is the integral solution over all columns.  The first solve scales by the largest
    cost; its value ``V`` (exact, from ``c``) bounds the optimum, so no
    column dearer than ``V`` can be in an optimal solution (the costs are
    nonnegative), and the second solve keeps the others, scaled by ``V``:
    every tolerance is then relative to the value itself.  The better of
    the two solutions is returned.  With ``once=True`` only the first solve
    runs (a guess, :func:`solve_torus`'s ``guess``).
    """
    def solve(cols, scale):
        res = run(cols, scale)
        if res.status != 0:
            raise DirectError(f"{infeasible} ({res.message})")
        x = np.zeros(len(c), dtype=int)
        x[cols] = np.rint(res.x).astype(int)
        return x

    top = float(c.max()) if len(c) else 0.0
    x = solve(np.arange(len(c)), top if top > 0 else 1.0)
    value = float(c @ x)
    if once or not 0.0 < value < top:
        return x
    cols = np.flatnonzero(c <= value)  # feasible: x uses none of the others
    try:
        x2 = solve(cols, value)
    except DirectError:  # numerical trouble on the pruned program: the first solution stands
        return x
    return x2 if float(c @ x2) < value else x


#: columns per row of the torus program that :func:`solve_torus` first seeks an incumbent on (by least reduced cost)
_INCUMBENT_COLUMNS = 4


def solve_torus(
    cost: dict, closed: dict, npos: int, nneg: int, winds: tuple[int, int], guess: bool = False
) -> tuple[float, list[tuple]]:
    """Program (34) on a torus ``S^1 x S^1``: a matching with prescribed homology.

    On the torus (two distinct circles of M) there is no boundary; the
    conditions of eq. (6) on the two non-contractible loops fix the total
    signed number of times the curves cross each seam.  Curves join negative
    to positive points, each in a homotopy class ``(k1, k2)`` (how many times
    it crosses the seams), and closed curves ``gamma: S^1 -> M x M`` (section
    3.3.4) add their classes.  This is an assignment with two side
    constraints, an integer program solved by :func:`scipy.optimize.milp`
    (HiGHS) on the columns that can matter only (see Notes).

    Parameters
    ----------
    cost : dict
        ``cost[(i, j, k)]``: length from negative point ``j`` to positive point
        ``i`` in class ``k = (k1, k2)``.
    closed : dict
        ``closed[k]``: length of the shortest closed curve of class ``k``.
    npos, nneg : int
        Numbers of positive and negative points (equal on a torus).
    winds : tuple of int
        Prescribed total seam crossings ``(K1, K2)``.
    guess : bool, optional
        Solve once, with HiGHS's tolerances relative to the largest cost
        rather than to the value (the first of :func:`_two_stage`'s two
        passes): a family optimal to about ``1e-6`` of the largest cost, for
        guessing which entries the program will use
        (``direct.penalty._foreseen``), not for its value.

    Returns
    -------
    value : float
    chosen : list of (key, count)
        ``key`` is ``(i, j, k)`` for a path, ``("closed", k)`` for closed curves.

    Raises
    ------
    DirectError
        If no family of curves meets the conditions.

    Notes
    -----
    With 9 classes per pair the program has ``9 n^2`` columns, and HiGHS's
    branch and cut spent 5 s at the root on 17 432 of them (44 pairs of
    points; two roses crossing each other) though the relaxation was
    integral.  The linear relaxation (HiGHS's dual simplex, 0.1 s) is solved
    first; an integral vertex of it is optimal.  Otherwise its duals ``y`` give reduced
    costs ``r = c - A^T y``; for every feasible ``x``, ``c x = b y + r x``
    exactly, whatever the accuracy of ``y``.  An incumbent of value ``U``
    from the integer program on the columns of least ``r`` then rules out
    every column with ``r > U - b y`` (plus the effect of any slightly
    negative ``r``), and the integer program on the columns left, scaled by
    ``U`` so that HiGHS's absolute tolerances are relative to the value,
    is the optimum over all of them.
    """
    from scipy import sparse
    from scipy.optimize import Bounds, LinearConstraint, linprog, milp

    infeasible = "no family of curves meets the conditions on the torus"
    keys = [k for k, c in cost.items() if np.isfinite(c)] + [("closed", k) for k, c in closed.items() if np.isfinite(c)]
    if not keys:
        if winds == (0, 0) and npos == nneg == 0:
            return 0.0, []
        raise DirectError(infeasible)
    path = np.array([k[0] != "closed" for k in keys])
    c = np.array([cost[k] if p else closed[k[1]] for k, p in zip(keys, path)], dtype=float)
    ends = np.array([k[:2] if p else (0, 0) for k, p in zip(keys, path)], dtype=int).reshape(-1, 2)
    klass = np.array([k[2] if p else k[1] for k, p in zip(keys, path)], dtype=float).reshape(-1, 2)
    n, cols = len(keys), np.arange(len(keys))
    # rows: one per positive point, one per negative point, the two seams
    A = sparse.csc_array(
        (np.concatenate([np.ones(2 * path.sum()), klass[:, 0], klass[:, 1]]),
         (np.concatenate([ends[path, 0], npos + ends[path, 1], np.full(n, npos + nneg), np.full(n, npos + nneg + 1)]),
          np.concatenate([cols[path], cols[path], cols, cols]))),
        shape=(npos + nneg + 2, n))
    b = np.concatenate([np.ones(npos + nneg), np.asarray(winds, dtype=float)])
    ub = np.where(path, 1.0, np.inf)

    def integral(on, scale):
        res = milp(c[on] / scale, constraints=LinearConstraint(A[:, on], b, b), integrality=np.ones(len(on)),
                   bounds=Bounds(np.zeros(len(on)), ub[on]), options={"mip_rel_gap": 0.0})
        if res.status != 0:
            return None
        x = np.zeros(n, dtype=int)
        x[on] = np.rint(res.x).astype(int)
        return x

    def program(cols, scale):
        """The program on the columns ``cols``, its costs over ``scale`` for HiGHS: an optimal ``x`` (or None)."""
        sub = A[:, cols]
        lp = linprog(c[cols] / scale, A_eq=sub, b_eq=b, bounds=(0, None), method="highs-ds", options=_HIGHS_LP)
        if lp.status == 2:
            return None
        if lp.status != 0:  # numerical trouble: the integer program on every column
            return integral(cols, scale)
        x = np.zeros(n, dtype=int)
        x[cols] = np.rint(lp.x).astype(int)
        if np.abs(lp.x - x[cols]).max() <= 1e-9 and np.array_equal(A @ x, b):
            # an integral vertex of the relaxation is optimal (HiGHS's integer program, with its looser
            # tolerances, settled 2e-7 above it on the roses' programs)
            return x
        r = np.full(n, np.inf)
        y = lp.eqlin.marginals * scale
        r[cols] = c[cols] - sub.T @ y
        bound = float(b @ y)
        # an incumbent from the columns of least reduced cost, more of them until one is found
        order = np.argsort(r, kind="stable")[:len(cols)]
        size = min(len(cols), max(_INCUMBENT_COLUMNS * (npos + nneg + 2), int(np.count_nonzero(r <= 1e-9 * scale)),
                                  1))
        while True:
            on = np.sort(order[:size])
            x = integral(on, max(bound, 1e-9 * scale))
            if x is not None or size == len(cols):
                break
            size = min(len(cols), 2 * size)
        if x is None:
            return None
        U = float(c @ x)
        # a feasible x' with x'_k > 0 costs c x' = b y + r x' >= b y + r_k + (number of curves in x') * min(r, 0),
        # and if no dearer than U it has npos paths and at most U / (cheapest closed curve) closed curves
        closed_costs = c[cols][~path[cols]]
        loops = (U / closed_costs.min() if closed_costs.size and closed_costs.min() > 0
                 else (0.0 if not closed_costs.size else np.inf))
        low = float(r[cols].min())
        slack = 0.0 if low >= 0 else -low * (npos + loops)
        keep = np.flatnonzero(r <= U - bound + slack + 1e-12 * max(abs(U), abs(bound)))
        if np.isfinite(slack) and np.isin(keep, on).all():
            return x  # the columns left are among those already solved over: x is optimal
        x2 = integral(keep if np.isfinite(slack) else cols, U if U > 0 else scale)
        return x2 if x2 is not None and float(c @ x2) < U else x

    def run(on, scale):  # for _two_stage: HiGHS's tolerances relative to the largest cost, then to the value
        x = program(on, scale)
        return SimpleNamespace(status=0, x=x[on]) if x is not None else SimpleNamespace(status=2, message="infeasible")

    best = _two_stage(run, c, infeasible, once=guess)
    return float(c @ best), [(keys[k], int(best[k])) for k in np.flatnonzero(best)]
