"""``direct.penalty(..., workers=N)``: the batches of curves refined on several processes give the same result."""

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import random_crossing_scene

import direct
from direct import parallel


def same(a: direct.Penalty, b: direct.Penalty) -> bool:
    """Bit for bit: value, estimate, upper bound and every curve."""
    return (a.value == b.value and a.error_estimate == b.error_estimate and a.upper_bound == b.upper_bound
            and len(a.pairs) == len(b.pairs)
            and all(p.length == q.length and p.error_estimate == q.error_estimate and np.array_equal(p.path, q.path)
                    for p, q in zip(a.pairs, b.pairs)))


@pytest.fixture
def parts_run(monkeypatch) -> list[int]:
    """The number of parts of every batch split over processes (so a test sees that it ran in parallel)."""
    sizes: list[int] = []
    run = parallel.run_parts

    def spy(fn, parts):
        sizes.append(len(parts))
        return run(fn, parts)

    monkeypatch.setattr(parallel, "run_parts", spy)
    return sizes


@pytest.mark.parametrize("seed", [3, 8])
def test_two_workers_give_the_result_of_one_bit_for_bit_on_intervals(seed, parts_run):
    scene = random_crossing_scene(seed, n_comp=3, n_vert=6, min_crossings=4, max_crossings=10)
    one = direct.penalty(scene)
    assert not parts_run  # one process: no batch is split
    two = direct.penalty(scene, workers=2)
    assert parts_run and max(parts_run) == 2
    assert same(one, two)


def test_two_workers_give_the_result_of_one_bit_for_bit_around_a_circle(parts_run):
    """A star polygon of 7 crossings (the circle with itself: shifted starts, corner starts, mirror images)."""
    scene = direct.scenes.circle_scene(lambda t: np.column_stack([np.cos(2 * t), np.sin(2 * t)]), n=7)
    assert same(direct.penalty(scene), direct.penalty(scene, workers=2))
    assert parts_run


def test_workers_with_a_quadrature_metric_agree_within_the_estimates(parts_run):
    """``G`` with ``q = 1`` integrates its pieces by Gauss-Legendre quadrature, a BLAS product over a batch whose
    last bit depends on the batch: the parts can settle elsewhere within their estimates (on this scene 2.0e-5
    apart, relative, with estimates of 4.6e-4; the two-process value the closer to ``J``).  The same number of
    workers gives the same result again."""
    scene = random_crossing_scene(5, n_comp=2, n_vert=6, min_crossings=3, max_crossings=8)
    one = direct.penalty(scene, "G", power=1)
    two = direct.penalty(scene, "G", power=1, workers=2)
    assert parts_run
    assert abs(two.value - one.value) <= one.error_estimate + two.error_estimate
    assert same(two, direct.penalty(scene, "G", power=1, workers=2))


def test_split_balances_the_work_and_keeps_every_index_once():
    costs = [5.0, 1.0, 4.0, 3.0, 3.0, 2.0]
    groups = parallel.split(costs, 2)
    assert sorted(i for g in groups for i in g) == list(range(len(costs)))
    assert all(g == sorted(g) for g in groups)
    loads = sorted(sum(costs[i] for i in g) for g in groups)
    assert loads == [9.0, 9.0]
    assert parallel.split([1.0, 2.0], 8) == [[1], [0]]  # no empty part
    assert parallel.split([], 3) == []


@pytest.mark.parametrize("workers", [0, -2, 1.5, True, "2", None, 1025, 2**40])
def test_workers_must_be_a_whole_number_of_processes(workers):
    with pytest.raises(direct.DirectError, match="workers must be a whole number"):
        direct.penalty("cross", workers=workers)


def test_all_cpus():
    assert parallel.resolve_workers(-1) >= 1
    assert parallel.resolve_workers(np.int64(3)) == 3


def test_the_command_line_takes_workers():
    proc = subprocess.run([sys.executable, "-m", "direct", "penalty", "cross60", "--workers", "2", "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["value"] == direct.penalty("cross60").value
    proc = subprocess.run([sys.executable, "-m", "direct", "penalty", "cross", "--workers", "0"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0 and "workers must be a whole number" in proc.stderr


def _square_or_die(x, parent):
    import os

    if os.getpid() != parent:
        os._exit(3)  # a worker killed mid-batch
    return x * x


def test_no_parts_come_back_when_the_workers_die():
    """The caller then does the whole batch itself, as with one process, and so does the rest of the call."""
    import os

    with parallel.using(3) as processes:
        assert parallel.run_parts(_square_or_die, [(2, os.getpid()), (3, os.getpid()), (4, os.getpid())]) is None
        assert "died" in processes.failure
        assert parallel.current() == 1
    with parallel.using(2):
        assert parallel.run_parts(pow, [(2, 3), (3, 2)]) == [8, 9]  # new workers


def test_the_batch_runs_here_when_no_worker_can_start(monkeypatch):
    def refuse(n):
        raise OSError("no processes here")

    monkeypatch.setattr(parallel, "_pool", refuse)
    scene = random_crossing_scene(3, n_comp=3, n_vert=6, min_crossings=4, max_crossings=10)
    with pytest.warns(RuntimeWarning, match="no worker process could start.*no processes here") as record:
        two = direct.penalty(scene, workers=2)
    assert len([w for w in record if w.category is RuntimeWarning]) == 1  # once a call, not once a batch
    assert record[0].filename == __file__  # it points at the call
    assert "no processes here" in two.settings["workers_failed"] and two.settings["workers"] == 2
    assert same(direct.penalty(scene), two)


def test_a_metric_that_cannot_go_to_another_process_is_refined_here():
    """A metric built on a lambda does not pickle: the call runs in this process, with a warning, as with one."""
    from direct.metric import GFamily

    metric = GFamily(lambda s: s**3, label="s^3")
    scene = random_crossing_scene(3, n_comp=3, n_vert=6, min_crossings=4, max_crossings=10)
    with pytest.warns(RuntimeWarning, match="cannot be sent to worker processes"):
        two = direct.penalty(scene, metric, workers=2)
    assert same(direct.penalty(scene, metric), two)


def _penalty_in_child(queue):
    import warnings

    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        value = direct.penalty("cross60", workers=2).value
    queue.put((value, [str(w.message) for w in record if w.category is RuntimeWarning]))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork")
def test_a_process_that_multiprocessing_forked_refines_by_itself():
    """Such a process inherits its parent's pool object but none of its processes (a review found it waiting
    forever on them), and its own workers kept its exit waiting: it refines alone, and says so."""
    import multiprocessing

    value = direct.penalty("cross60", workers=2).value
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_penalty_in_child, args=(queue,))
    child.start()
    got, messages = queue.get(timeout=120)
    child.join(timeout=30)
    assert child.exitcode == 0
    assert got == value
    assert len(messages) == 1 and "not from one that multiprocessing started" in messages[0]


def test_one_pool_of_workers_minus_one_processes():
    """Batches with fewer parts than workers use the same pool; another number of workers replaces it."""
    scene = random_crossing_scene(8, n_comp=3, n_vert=6, min_crossings=4, max_crossings=10)
    direct.penalty(scene, workers=3)
    pool, size = parallel._POOL[0], parallel._POOL[1]
    assert size == 2
    direct.penalty(scene, workers=3)
    assert parallel._POOL[0] is pool
    parallel.shutdown()
    assert parallel._POOL[0] is None
    direct.penalty(scene, workers=2)
    assert parallel._POOL[1] == 1


def test_a_curve_whose_block_is_not_finite_leaves_the_others_alone():
    """The stacked Newton solves every curve's tridiagonal block in one call, where a non-finite entry would turn
    every curve's step into NaN (a review): the curves are then solved one by one, each as alone."""
    from types import SimpleNamespace

    from direct.refinement import _solve_tridiagonal

    stack = SimpleNamespace(u_curve=np.array([0, 0, 1, 1]))
    diag = np.array([np.nan, 2.0, 3.0, 3.0])  # one bad entry in the first curve's block
    off = np.array([0.5, 0.0, 1.0])
    rhs = np.array([1.0, 1.0, 1.0, 1.0])
    dz = _solve_tridiagonal(stack, diag, off, rhs, np.ones(4, dtype=bool))
    alone = _solve_tridiagonal(SimpleNamespace(u_curve=np.array([1, 1])), diag[2:], off[2:], rhs[2:],
                               np.ones(2, dtype=bool))
    assert np.array_equal(dz[2:], alone) and np.allclose(alone, [0.25, 0.25])
    assert not np.isfinite(dz[:2]).any()  # the bad curve's own step says so (the Newton loop damps it)
