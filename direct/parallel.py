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
The ``workers - 1`` worker processes are started at the first call and kept
for the session (a :class:`concurrent.futures.ProcessPoolExecutor`; another
``workers`` replaces them): by ``fork`` on Linux, so nothing is imported
again; elsewhere by ``spawn``, which imports the main module again in each
worker, so a script that asks for workers needs the usual ``if __name__ ==
"__main__":`` guard.  Workers keep the code and settings of the moment they
started (a module changed or reloaded afterwards, numpy's error settings,
warning filters): :func:`shutdown` stops them, and the next call starts new
ones.  Each worker keeps BLAS on one thread, as :func:`direct.penalty` does,
and ignores Ctrl-C, which the calling process receives.  Only a main process
starts workers: in a process that :mod:`multiprocessing` started (a pool's
worker, a forked child), a call runs in that process.

Where no worker can take a part (arguments that do not pickle, such as a
metric built on a lambda; a process that multiprocessing started; workers
that cannot start or die), the rest of that call runs in the calling
process, as with one process, and :func:`direct.penalty` says why in one
``RuntimeWarning``.
"""

from __future__ import annotations

import atexit
import contextlib
import contextvars
import os
import sys

import numpy as np

from .errors import DirectError

__all__ = ["resolve_workers", "using", "current", "split", "run_parts", "shutdown"]


class Setting:
    """The processes a call may use: ``workers``, and ``failure``, why the rest of the call runs here (or None)."""

    __slots__ = ("workers", "failure")

    def __init__(self, workers: int):
        self.workers = workers
        self.failure: str | None = None


_SETTING: contextvars.ContextVar[Setting | None] = contextvars.ContextVar("direct_workers", default=None)
#: the worker processes of this session: [executor, its number of processes, the pid that started it]
_POOL: list = [None, 0, 0]


#: the most processes ``workers`` may ask for (2**40 overflowed in the pool: a review at stop 48)
_MAX_WORKERS = 1024


def resolve_workers(workers) -> int:
    """The number of processes ``workers`` asks for.

    Parameters
    ----------
    workers : int
        A whole number of processes, from 1 to 1024, or -1 for every CPU
        this process may run on.

    Returns
    -------
    int

    Raises
    ------
    DirectError
        For anything else (0, -2, 1.5, 2**40, a string, a bool).
    """
    ok = isinstance(workers, (int, np.integer)) and not isinstance(workers, (bool, np.bool_))
    if not ok or not (1 <= workers <= _MAX_WORKERS or workers == -1):
        raise DirectError(f"workers must be a whole number of processes, from 1 to {_MAX_WORKERS}, or -1 for every "
                          f"CPU, got {workers!r}")
    if workers == -1:
        return max(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1), 1)
    return int(workers)


@contextlib.contextmanager
def using(workers: int):
    """Context in which :func:`direct.refinement.refine_many` splits its batches over ``workers`` processes.

    Parameters
    ----------
    workers : int
        Processes, the calling one included (1: no split).

    Yields
    ------
    Setting
        Its ``failure`` is set (a message) when no worker could take a part;
        the rest of the context then runs in this process.
    """
    setting = Setting(int(workers))
    token = _SETTING.set(setting)
    try:
        yield setting
    finally:
        _SETTING.reset(token)


def current() -> int:
    """The number of processes the batches of this context may use (1 outside :func:`using`, or after a failure)."""
    setting = _SETTING.get()
    return 1 if setting is None or setting.failure is not None else setting.workers


def split(costs, parts: int) -> list[list[int]]:
    """Indices grouped into ``parts`` groups of about equal total cost (the costliest first, to the lightest group).

    Parameters
    ----------
    costs : sequence of float
        The work of each item.
    parts : int
        The number of groups wanted.

    Returns
    -------
    list of list of int
        Every index once, each group in increasing order; no empty group
        (fewer groups than ``parts`` when there are fewer items).
    """
    costs = np.asarray(costs, dtype=float)
    groups: list[list[int]] = [[] for _ in range(max(1, min(parts, len(costs))))]
    load = np.zeros(len(groups))
    for i in np.argsort(-costs, kind="stable"):
        g = int(np.argmin(load))
        groups[g].append(int(i))
        load[g] += costs[i]
    return [sorted(g) for g in groups if g]


def _start_method() -> str:
    return "fork" if sys.platform.startswith("linux") else "spawn"


def _pool(size: int):
    """The session's ``size`` worker processes (started now if none, another number, or another process's)."""
    import multiprocessing  # here, not at import: only a call with workers needs them (14 ms of direct's import)
    import signal
    from concurrent.futures import ProcessPoolExecutor

    executor, n, pid = _POOL
    if executor is not None and (pid != os.getpid() or n != size):
        if pid == os.getpid():
            executor.shutdown(wait=False, cancel_futures=True)
        executor = None  # a forked child's copy has no processes behind it: it is dropped, not shut down
    if executor is None:
        executor = ProcessPoolExecutor(max_workers=size, mp_context=multiprocessing.get_context(_start_method()),
                                       initializer=signal.signal, initargs=(signal.SIGINT, signal.SIG_IGN))
        _POOL[:] = [executor, size, os.getpid()]
        # let go of it at exit, while the modules it calls back into are still there
        atexit.unregister(shutdown)
        atexit.register(shutdown)
    return executor


def shutdown() -> None:
    """Stop the worker processes of this session (the next call with ``workers > 1`` starts new ones).

    Workers keep the code and settings of the moment they started: after
    changing a module, call this.
    """
    executor, _, pid = _POOL
    _POOL[:] = [None, 0, 0]
    if executor is not None and pid == os.getpid():
        executor.shutdown(wait=True, cancel_futures=True)


def _in_worker(fn, args):
    from .penalty import _one_blas_thread

    with _one_blas_thread(), using(1):  # a forked worker inherits the context that started it
        return fn(*args)


def run_parts(fn, parts: list[tuple]) -> list | None:
    """``[fn(*args) for args in parts]``: the first part here, the others on worker processes, at once.

    Parameters
    ----------
    fn : callable
        A module-level function (it goes to the workers by name).
    parts : list of tuple
        The arguments of each call; at most :func:`current` of them.

    Returns
    -------
    list or None
        The results, in order.  None where no worker could take a part
        (the arguments do not pickle, such as a metric built on a lambda;
        worker processes cannot start, as in a daemonic process, or die):
        the context's ``failure`` then says why, the rest of the context
        runs in this process, and the caller does this whole work itself,
        as with one process.  The call here runs with ``using(1)``, so
        ``fn`` does not split again; an error that ``fn`` raises in a
        worker is raised here.
    """
    from concurrent.futures.process import BrokenProcessPool

    futures = _submit(fn, parts[1:]) if len(parts) > 1 else []
    if len(parts) > 1 and not futures:
        return None
    with using(1):
        out = [fn(*parts[0])]
    try:
        return out + [f.result() for f in futures]
    except BrokenProcessPool as exc:
        _POOL[:] = [None, 0, 0]
        _fail(f"the worker processes died ({exc})")
        return None


def _submit(fn, rest: list[tuple]) -> list:
    """Futures of ``fn(*args)`` for each of ``rest`` on the workers; none where they cannot go there (see _fail)."""
    import multiprocessing
    import pickle
    from concurrent.futures.process import BrokenProcessPool

    if multiprocessing.parent_process() is not None:
        # a process that multiprocessing started (a daemonic pool's worker may have no children; a forked one's
        # workers kept its exit waiting forever, in a review's script and a test): no workers of its own
        _fail("worker processes start only from a main process, not from one that multiprocessing started")
        return []
    try:
        pickle.dumps((fn, rest[0]))
    except (pickle.PicklingError, AttributeError, TypeError) as exc:
        _fail(f"its arguments cannot be sent to worker processes ({type(exc).__name__}: {exc}); define the metric's "
              "functions at module level to use workers")
        return []
    try:
        pool = _pool(max(current() - 1, len(rest)))
        return [pool.submit(_in_worker, fn, args) for args in rest]
    except (OSError, AssertionError, BrokenProcessPool) as exc:
        _POOL[:] = [None, 0, 0]
        guard = ("; a script needs an 'if __name__ == \"__main__\":' guard where workers start by spawn"
                 if _start_method() == "spawn" else "")
        _fail(f"no worker process could start ({type(exc).__name__}: {exc}){guard}")
        return []


def _fail(reason: str) -> None:
    """Record why no worker takes this context's parts: the rest of it runs here (see :func:`using`)."""
    setting = _SETTING.get()
    if setting is not None and setting.failure is None:
        setting.failure = reason
