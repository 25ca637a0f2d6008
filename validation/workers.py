"""One process against several: ``direct.penalty(..., workers=N)``, side by side on the same scenes.

Run ``python validation/workers.py`` (about seven minutes on 2 cores; ``--workers`` sets N, default 2).
Every scene is solved with one process and with N, alternately (``--rounds`` times, default 2; the
best time of each kept), after a warm-up call that starts the worker processes.  The metric is the
default ``G`` (``q = 2``), whose results must be the same bit for bit (value, estimate, upper bound and
every curve): the script stops with an error otherwise.

Scenes: the star polygons of 7, 11 and 15 vertices (double covers, as in ``ab.py --family
circles``), the built-in ``fig10`` and ``nested``, the first 8 random closed polygons of
``random_closed.py`` that cross and the random interval scenes of ``default_tol.py`` among seeds 100
to 119 (``tests/conftest.py``'s ``study_scenes``: 19 scenes), all at ``tol=1e-3``, and the star of
7 vertices at ``tol=1e-5``.

Writes ``workers.csv`` (one row per scene: the two best times, their ratio, the value) and
``workers.png`` (the time with N processes against the time with one, log-log) beside this file, and
prints the ratio per family (the sum of the times with one process over the sum with N).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
sys.path.insert(0, HERE)
from conftest import study_scenes  # noqa: E402
from failures import double_cover as star  # noqa: E402  (odd n: a star polygon of n crossings)
from random_closed import random_closed  # noqa: E402
from study import write_csv  # noqa: E402

import direct  # noqa: E402


def scenes() -> list[tuple[str, str, direct.Scene, float]]:
    """``(family, name, scene, tol)`` of every call."""
    out = [("circles", f"star {n}", star(n), 1e-3) for n in (7, 11, 15)]
    out += [("circles", name, direct.scenes.get(name), 1e-3) for name in ("fig10", "nested")]
    closed = [(seed, random_closed(seed)) for seed in range(22)]
    out += [("closed polygons", f"closed {seed}", sc, 1e-3) for seed, sc in closed if direct.find_crossings(sc)][:8]
    out += [("intervals", f"seed {seed}", sc, 1e-3) for seed, sc in study_scenes(range(100, 120))]
    out += [("circles at 1e-5", "star 7", star(7), 1e-5)]
    return out


def _same(a: direct.Penalty, b: direct.Penalty) -> bool:
    return (a.value == b.value and a.error_estimate == b.error_estimate and a.upper_bound == b.upper_bound
            and len(a.pairs) == len(b.pairs)
            and all(p.length == q.length and np.array_equal(p.path, q.path) for p, q in zip(a.pairs, b.pairs)))


def main(workers: int = 2, rounds: int = 2) -> list[dict]:
    warnings.simplefilter("ignore", direct.ToleranceWarning)
    direct.penalty("cross", workers=workers)  # starts the worker processes
    rows = []
    for family, name, scene, tol in scenes():
        best = {1: np.inf, workers: np.inf}
        results = {}
        for _ in range(rounds):
            for n in (1, workers):
                t = time.perf_counter()
                results[n] = direct.penalty(scene, tol=tol, workers=n)
                best[n] = min(best[n], time.perf_counter() - t)
        if not _same(results[1], results[workers]):
            raise SystemExit(f"{name} at tol={tol}: {workers} workers gave {results[workers].value!r}, one process "
                             f"{results[1].value!r}")
        rows.append(dict(family=family, scene=name, tol=tol, seconds_1=best[1], seconds_n=best[workers],
                         workers=workers, ratio=best[1] / best[workers], value=results[1].value))
        print(f"{family:16s} {name:10s} tol={tol:g}: {best[1]:7.2f} s / {best[workers]:7.2f} s = "
              f"{best[1] / best[workers]:.2f}", flush=True)
    return rows


def chart(rows: list[dict], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 5))
    for family, marker in zip(dict.fromkeys(r["family"] for r in rows), "osD^v"):
        sel = [r for r in rows if r["family"] == family]
        ax.loglog([r["seconds_1"] for r in sel], [r["seconds_n"] for r in sel], marker, label=family, alpha=0.8)
    lo = min(min(r["seconds_1"], r["seconds_n"]) for r in rows) / 1.5
    hi = max(max(r["seconds_1"], r["seconds_n"]) for r in rows) * 1.5
    n = rows[0]["workers"]
    ax.plot([lo, hi], [lo, hi], "k:", lw=1, label="the same time")
    ax.plot([lo, hi], [lo / n, hi / n], "k--", lw=1, label=f"{n} times faster")
    ax.set_xlabel("one process (s)")
    ax.set_ylabel(f"{n} worker processes (s)")
    ax.set_title(f"direct.penalty(..., workers={n}): the same values, less time")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    rows = main(args.workers, args.rounds)
    write_csv(rows, os.path.join(HERE, "workers.csv"))
    chart(rows, os.path.join(HERE, "workers.png"))
    for family in dict.fromkeys(r["family"] for r in rows):
        sel = [r for r in rows if r["family"] == family]
        one, many = sum(r["seconds_1"] for r in sel), sum(r["seconds_n"] for r in sel)
        print(f"{family}: {len(sel)} scenes, {one:.1f} s with one process, {many:.1f} s with {args.workers}: "
              f"{one / many:.2f} times faster; every value the same")
