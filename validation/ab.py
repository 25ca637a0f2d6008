"""Time two commits of ``direct`` against each other on the same scenes, alternately, in one run.

Run ``python validation/ab.py REV`` (for example ``python validation/ab.py HEAD~1``; about a minute).
It checks ``REV`` out into a temporary git worktree, then times the working tree's ``direct`` and
``REV``'s alternately, each in a fresh process (``--rounds`` times, best of ``--repeat`` calls per
scene and process), so that the noise of this shared machine hits both alike.  It writes
``validation/ab.csv`` (one row per process and scene) and prints the ratio of the medians of the
best times per scene, with the values both versions return.

Scenes (``--family standard``): zigzags of 10 and 100 crossings through a line (``benchmark.zigzag``),
the 60-degree crossing ``cross60`` and the figure eight ``fig10`` (a circle with itself).  ``--family
random``: the random interval scenes of ``validation/default_tol.py`` (2 or 3 polylines of 7
vertices, 1 to 10 crossings), seeds 100 to 116.  ``--family circles``: the star polygons of 7, 11 and 15
vertices (double covers sampled with an odd number of vertices, ``double_cover`` of
``validation/failures.py``) and the built-in ``fig10``, ``fig13`` and ``nested`` (no warm-up call: use
``--repeat 1``)  ``--family tori``: pairs of closed polygons from
``closed_searches.py`` (two regular 16-gons 1.0 apart, 32-gons 0.6 and 0.3 apart, the random pairs 0, 6
and 8) and ``nested``.  ``--tol`` (default 1e-3) is passed to every call;
``--csv`` names the output (default ``ab.csv``).  For example ``python validation/ab.py HEAD~1
--family random --tol 1e-6 --rounds 2 --repeat 1 --csv ab_random.csv`` (about six minutes).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile

import numpy as np
from study import write_csv

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

CHILD = r"""
import json, sys, time
sys.path.insert(0, {validation!r})
sys.path.insert(0, {tests!r})
import warnings
import direct
warnings.simplefilter("ignore", direct.ToleranceWarning)
if {family!r} == "standard":
    from benchmark import zigzag
    scenes = {{"zigzag10": zigzag(10), "zigzag100": zigzag(100), "cross60": direct.scenes.get("cross60"),
              "fig10": direct.scenes.get("fig10")}}
elif {family!r} == "circles":
    import numpy as np
    scenes = {{f"star{{n}}": direct.scenes.circle_scene(
        lambda t: np.column_stack([np.cos(2 * t), np.sin(2 * t)]), n=n, name=f"double cover n={{n}}")
        for n in (7, 11, 15)}}
    scenes.update({{name: direct.scenes.get(name) for name in ("fig10", "fig13", "nested")}})
elif {family!r} == "tori":
    from closed_searches import random_pair
    from conftest import polygon_pair
    scenes = {{f"{{n}}-gons {{shift}}": polygon_pair(n, shift) for n, shift in ((16, 1.0), (32, 0.6), (32, 0.3))}}
    scenes.update({{f"pair{{seed}}": random_pair(seed) for seed in (0, 6, 8)}})
    scenes["nested"] = direct.scenes.get("nested")
else:
    from conftest import random_crossing_scene
    scenes = {{}}
    for seed in range(100, 117):
        try:
            scenes[f"seed{{seed}}"] = random_crossing_scene(seed, n_comp=2 + seed % 2, n_vert=7, min_crossings=1,
                                                           max_crossings=10)
        except RuntimeError:
            pass
out = {{}}
for name, sc in scenes.items():
    if {family!r} == "standard":
        res = direct.penalty(sc, tol={tol!r})  # warm up
    best = float("inf")
    for _ in range({repeat}):
        t0 = time.perf_counter()
        res = direct.penalty(sc, tol={tol!r})
        best = min(best, time.perf_counter() - t0)
    out[name] = (best, res.value, res.error_estimate)
print(json.dumps(out))
"""


@contextlib.contextmanager
def worktree(rev: str | None):
    """The path of a checkout of ``rev`` in a temporary git worktree, removed on exit; ``None``: the working tree."""
    if rev is None:
        yield ROOT
        return
    with tempfile.TemporaryDirectory() as tmp:
        tree = os.path.join(tmp, "tree")
        subprocess.run(["git", "worktree", "add", "--detach", "-q", tree, rev], cwd=ROOT, check=True)
        try:
            yield tree
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", tree], cwd=ROOT, check=False)


def at_revision(rev: str, code: str) -> None:
    """Run ``code`` (Python, with this directory importable) against the ``direct`` of git revision ``rev``.

    The studies' ``--rev REV``: the revision is checked out into a temporary worktree (:func:`worktree`),
    and ``code`` runs in a fresh process whose ``import direct`` finds that checkout.
    """
    with worktree(rev) as tree:
        subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {HERE!r}); {code}"], cwd=tree,
                       env=dict(os.environ, PYTHONPATH=tree), check=True)


def run(tree: str, repeat: int, family: str = "standard", tol: float = 1e-3) -> dict:
    """Best times and values of the ``direct`` in ``tree``, measured in a fresh process."""
    code = CHILD.format(validation=HERE, tests=os.path.join(ROOT, "tests"), repeat=repeat, family=family, tol=tol)
    env = dict(os.environ, PYTHONPATH=tree)
    out = subprocess.run([sys.executable, "-c", code], cwd=tree, env=env, check=True, capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev", help="the git revision to compare the working tree with")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--family", choices=["standard", "random", "circles", "tori"], default="standard")
    ap.add_argument("--tol", type=float, default=1e-3)
    ap.add_argument("--csv", default="ab.csv", help="output file name, beside this script")
    args = ap.parse_args(argv)
    rows = []
    with worktree(args.rev) as old:
        for r in range(args.rounds):
            for label, tree in (("old", old), ("new", ROOT)):
                for scene, (sec, value, est) in run(tree, args.repeat, args.family, args.tol).items():
                    rows.append(dict(round=r, version=label, scene=scene, seconds=sec, value=value,
                                     error_estimate=est))
    write_csv(rows, os.path.join(HERE, args.csv))
    print(f"old = {args.rev}, new = working tree, tol={args.tol:g}; median over {args.rounds} rounds of the best of "
          f"{args.repeat} calls")
    for scene in dict.fromkeys(r["scene"] for r in rows):
        t = {v: float(np.median([r["seconds"] for r in rows if r["scene"] == scene and r["version"] == v]))
             for v in ("old", "new")}
        val = {v: next(r["value"] for r in rows if r["scene"] == scene and r["version"] == v) for v in ("old", "new")}
        print(f"{scene:10s} old {t['old']:.4f} s  new {t['new']:.4f} s  old/new {t['old'] / t['new']:.2f}  "
              f"values {val['old']:.10g} / {val['new']:.10g}")
    total = {v: sum(float(np.median([r["seconds"] for r in rows if r["scene"] == sc and r["version"] == v]))
                    for sc in dict.fromkeys(r["scene"] for r in rows)) for v in ("old", "new")}
    print(f"all scenes: old {total['old']:.2f} s  new {total['new']:.2f} s  old/new {total['old'] / total['new']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
