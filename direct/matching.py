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

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["solve", "brute_force"]


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
