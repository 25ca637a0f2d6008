"""Refinement batches on several processes: ``direct.penalty(..., workers=N)``.

The curves of a batch (:func:`direct.refinement.refine_many`) are refined
independently of each other: each has its own damping, step, line search,
rounds and levels, and a curve refined with others gets the numbers it gets
alone (``tests/test_refinement.py``).  So a batch can be cut into parts, one
refined here and the others on worker processes, and the result is the same,
bit for bit, where the metric's piece integrals have a closed form (``G`` with
``q = 2``, the default, and ``g`` with ``p = 1``).  Other metrics integrate by
Gauss-Legendre quadrature, a BLAS product over the batch whose last bit
depends on the batch; the refinement can then settle elsewhere within its
estimate, as it can when a curve is refined in another batch with one
process (``G`` with ``q = 1`` on one random scene: 2.0e-5 apart, relative,
with estimates of 4.6e-4).  A given number of workers gives the same result
again.  ``tests/test_parallel.py`` checks values, estimates and curves
against one process; ``python validation/workers.py`` measures the gain.

The parts are balanced by an estimate of each curve's work (:func:`split`).
Worker processes are started once per number of workers and kept for the
session (a :class:`concurrent.futures.ProcessPoolExecutor`): by ``fork`` on
Linux, so nothing is imported again; elsewhere by ``spawn``, which imports
the main module again in each worker, so a script that asks for workers
needs the usual ``if __name__ == "__main__":`` guard.  Each worker keeps
BLAS on one thread, as :func:`direct.penalty` does.
"""

from __future__ import annotations

import contextlib
import contextvars
import multiprocessing
import os
import pickle
import sys
import warnings
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

import numpy as np

from .errors import DirectError

__all__ = ["resolve_workers", "using", "current", "split", "run_parts"]

_WORKERS: contextvars.ContextVar[int] = contextvars.ContextVar("direct_workers", default=1)
_POOLS: dict[int, ProcessPoolExecutor] = {}


def resolve_workers(workers) -> int:
    """The number of processes ``workers`` asks for: a whole number of at least 1, or -1 for every CPU.

    Raises
    ------
    DirectError
        For anything else (0, -2, 1.5, a string, a bool).
    """
    ok = isinstance(workers, (int, np.integer)) and not isinstance(workers, (bool, np.bool_))
    if not ok or not (workers >= 1 or workers == -1):
        raise DirectError(f"workers must be a whole number of processes, at least 1, or -1 for every CPU, "
                          f"got {workers!r}")
    if workers == -1:
        return max(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1), 1)
    return int(workers)


@contextlib.contextmanager
def using(workers: int):
    """Context in which :func:`direct.refinement.refine_many` splits its batches over ``workers`` processes."""
    token = _WORKERS.set(int(workers))
    try:
        yield
    finally:
        _WORKERS.reset(token)


def current() -> int:
    """The number of processes the batches of this context may use (1 outside :func:`using`)."""
    return _WORKERS.get()


def split(costs, parts: int) -> list[list[int]]:
    """Indices of ``costs`` in ``parts`` groups of about equal total cost (longest first to the lightest group).

    Each group keeps its indices in increasing order; empty groups are dropped.
    """
    costs = np.asarray(costs, dtype=float)
    groups: list[list[int]] = [[] for _ in range(max(1, min(parts, len(costs))))]
    load = np.zeros(len(groups))
    for i in np.argsort(-costs, kind="stable"):
        g = int(np.argmin(load))
        groups[g].append(int(i))
        load[g] += costs[i]
    return [sorted(g) for g in groups if g]


def _pool(n: int) -> ProcessPoolExecutor:
    pool = _POOLS.get(n)
    if pool is None:
        method = "fork" if sys.platform.startswith("linux") else "spawn"
        pool = _POOLS[n] = ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context(method))
    return pool


def _in_worker(fn, args):
    from .penalty import _one_blas_thread

    with _one_blas_thread(), using(1):  # a forked worker inherits the context that started it
        return fn(*args)


def run_parts(fn, parts: list[tuple]) -> list | None:
    """``[fn(*args) for args in parts]``: the first part here, the others on worker processes, at once.

    The call here runs with one process (``using(1)``), so ``fn`` does not
    split again.  An error that ``fn`` raises in a worker is raised here.
    Where the arguments do not pickle (a metric built on a lambda), or worker
    processes cannot be started or die (a daemonic process may not have
    children; a worker killed), returns None, with a ``RuntimeWarning``:
    the caller then does the whole work itself, as with one process.
    """
    futures = _submit(fn, parts[1:]) if len(parts) > 1 else []
    if len(parts) > 1 and not futures:
        return None
    with using(1):
        out = [fn(*parts[0])]
    try:
        return out + [f.result() for f in futures]
    except BrokenProcessPool as exc:
        _broken(len(parts) - 1, exc)
        return None


def _submit(fn, rest: list[tuple]) -> list:
    """Futures of ``fn(*args)`` for each of ``rest`` on the pool; none (with a warning) where they cannot go there."""
    try:
        pickle.dumps((fn, rest[0]))
    except (pickle.PicklingError, AttributeError, TypeError) as exc:  # a metric built on a lambda, say
        warnings.warn(f"direct: these arguments cannot be sent to worker processes ({type(exc).__name__}: {exc}); "
                      "refining in this process instead (as with workers=1); define the metric's functions at "
                      "module level to use workers", RuntimeWarning, stacklevel=4)
        return []
    try:
        pool = _pool(len(rest))
        return [pool.submit(_in_worker, fn, args) for args in rest]
    except (OSError, AssertionError, BrokenProcessPool) as exc:
        _broken(len(rest), exc)
        return []


def _broken(n: int, exc: BaseException) -> None:
    """Forget the pool of ``n`` workers and say that the parts run here instead."""
    _POOLS.pop(n, None)
    warnings.warn(f"direct: worker processes unavailable ({type(exc).__name__}: {exc}); refining in this process "
                  "instead (as with workers=1)", RuntimeWarning, stacklevel=4)
