"""Do two versions of ``direct`` return the same values?  Bit for bit, on the scenes of the studies.

Run ``python validation/same_values.py OLD [NEW]`` (for example ``python validation/same_values.py HEAD~1``;
about twenty-two minutes with every family, two processes side by side).  ``OLD`` and ``NEW`` are git revisions,
checked out into temporary worktrees; without ``NEW`` the working tree is the new version.  Both run the
same calls of ``direct.penalty``, each in its own process (the two at once, on two cores), and the script
compares every value and ``error_estimate`` bit for bit and prints, per family and tolerance, how many
are identical, the largest relative change of the others against their estimates, and the total times.

Families (``--families``, default all): ``builtin``, every built-in scene with ``G`` and ``g`` at
``tol=1e-3`` and ``1e-5``; ``intervals``, the 175 random interval scenes of ``default_tol.py``
(``tests/conftest.py``'s ``study_scenes``, seeds 100 to 299) at ``tol=1e-3``, ``1e-4`` and ``1e-5``;
``closed``, the random closed polygons of ``random_closed.py`` (seeds 0 to 59) at ``1e-3`` and
``1e-5``; ``tori``, the 45 pairs of polygons of ``closed_searches.py``; ``multistart``, the scenes of
``multistart.py`` (seeds 100 to 139) at ``tol=1e-5`` on grids of 96 and 192 cells.  Writes
``same_values.csv`` beside this file (one row per call: both values, estimates and times).

The times are those of one call each, with the two processes sharing the machine: read them as a
rough ratio; ``ab.py`` times two versions properly (alternating fresh processes).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from ab import worktree  # noqa: E402  (a checkout of a revision in a temporary git worktree)
from study import write_csv  # noqa: E402

FAMILIES = ("builtin", "intervals", "closed", "tori", "multistart")

CHILD = r"""
import json, sys, time, warnings
sys.path.insert(0, {validation!r})
sys.path.insert(0, {tests!r})
import direct
from conftest import study_scenes
warnings.simplefilter("ignore")
families = {families!r}
out = open({out!r}, "w")


def run(family, name, scene, **kwargs):
    t0 = time.perf_counter()
    try:
        res = direct.penalty(scene, **kwargs)
        value, estimate = res.value, res.error_estimate
    except direct.DirectError as exc:  # recorded as text: the same error on both sides counts as the same
        value, estimate = type(exc).__name__ + ": " + str(exc)[:80], None
    out.write(json.dumps(dict(family=family, scene=str(name), settings=json.dumps(kwargs, sort_keys=True),
                              value=value, error_estimate=estimate, seconds=time.perf_counter() - t0)) + "\n")
    out.flush()


if "builtin" in families:
    for name in direct.scenes.names():
        for metric in ("G", "g"):
            for tol in (1e-3, 1e-5):
                run("builtin", name, name, metric=metric, tol=tol)
if "intervals" in families:
    scenes = list(study_scenes(range(100, 300)))
    for tol in (1e-3, 1e-4, 1e-5):
        for seed, sc in scenes:
            run("intervals", seed, sc, tol=tol)
if "closed" in families:
    from random_closed import random_closed
    for tol in (1e-3, 1e-5):
        for seed in range(60):
            run("closed", seed, random_closed(seed), tol=tol)
if "tori" in families:
    from closed_searches import scenes as tori
    for k, sc in enumerate(tori()):
        run("tori", f"{{k}} {{sc.name}}", sc)
if "multistart" in families:
    for seed, sc in study_scenes(range(100, 140)):
        for resolution in (96, 192):
            run("multistart", seed, sc, tol=1e-5, resolution=resolution)
"""


def _start(tree: str, families: list[str], out: str) -> subprocess.Popen:
    code = CHILD.format(validation=HERE, tests=os.path.join(ROOT, "tests"), families=families, out=out)
    env = dict(os.environ, PYTHONPATH=tree)
    return subprocess.Popen([sys.executable, "-c", code], cwd=tree, env=env)


def _read(path: str) -> dict:
    with open(path) as fh:
        rows = [json.loads(line) for line in fh]
    return {(r["family"], r["scene"], r["settings"]): r for r in rows}


def _bits(x) -> str:
    """A value as its exact text: floats by ``repr`` (so -0.0 differs from 0.0 and a NaN equals a NaN)."""
    return repr(float(x)) if isinstance(x, (int, float)) else repr(x)


def compare(old: dict, new: dict) -> list[dict]:
    """One row per call present in both runs (the calls present in one only are printed)."""
    only = sorted(set(old) ^ set(new))
    if only:
        print(f"{len(only)} calls in one run only (each version builds its scenes): {only[:5]}")
    rows = []
    for key, a in old.items():
        if key not in new:
            continue
        b = new[key]
        same = (_bits(a["value"]) == _bits(b["value"])
                and _bits(a["error_estimate"]) == _bits(b["error_estimate"]))
        change = ""
        if not same and isinstance(a["value"], float) and isinstance(b["value"], float) and a["value"]:
            change = abs(b["value"] - a["value"]) / abs(a["value"])
        rows.append(dict(family=key[0], scene=key[1], settings=key[2], identical=same, old_value=a["value"],
                         new_value=b["value"], old_estimate=a["error_estimate"], new_estimate=b["error_estimate"],
                         relative_change=change, old_seconds=a["seconds"], new_seconds=b["seconds"]))
    return rows


def summary(rows: list[dict]) -> str:
    lines = []
    groups: dict = {}
    for r in rows:
        tol = json.loads(r["settings"]).get("tol", 1e-3)
        groups.setdefault((r["family"], tol), []).append(r)
    for (family, tol), rs in groups.items():
        same = sum(r["identical"] for r in rs)
        t_old, t_new = sum(r["old_seconds"] for r in rs), sum(r["new_seconds"] for r in rs)
        line = (f"{family} tol={tol:g}: {same} of {len(rs)} identical; time {t_old:.0f} s -> {t_new:.0f} s "
                f"(old/new {t_old / t_new:.2f})")
        diff = [r for r in rs if not r["identical"]]
        measured = [r for r in diff if r["relative_change"] != ""]  # two nonzero floats
        if measured:
            worst = max(measured, key=lambda r: r["relative_change"])
            est = worst["old_estimate"] / abs(worst["old_value"]) if worst["old_estimate"] else float("nan")
            line += (f"; largest change {worst['relative_change']:.1e} relative ({worst['scene']}, "
                     f"old estimate {est:.1e} relative)")
        if diff:
            line += f"; changed: {', '.join(r['scene'] for r in diff)}"
            line += "".join(f"; {r['scene']}: {r['old_value']!r} -> {r['new_value']!r}"
                            for r in diff if r["relative_change"] == "")
        lines.append(line)
    return "\n".join(lines)


def main(argv=None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("old", help="the old revision")
    parser.add_argument("new", nargs="?", help="the new revision (default: the working tree)")
    parser.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    parser.add_argument("--csv", default="same_values.csv")
    args = parser.parse_args(argv)
    with contextlib.ExitStack() as stack:
        tmp = stack.enter_context(tempfile.TemporaryDirectory())
        trees = {side: stack.enter_context(worktree(rev)) for side, rev in (("old", args.old), ("new", args.new))}
        outs = {side: os.path.join(tmp, f"{side}.jsonl") for side in trees}
        procs = [_start(trees[side], args.families, outs[side]) for side in ("old", "new")]
        codes = [p.wait() for p in procs]  # both, before their worktrees go
        if any(codes):
            raise SystemExit(f"a run failed (exit codes {codes}; see its traceback above)")
        rows = compare(_read(outs["old"]), _read(outs["new"]))
    if not rows:
        raise SystemExit("no call in common between the two runs")
    write_csv(rows, os.path.join(HERE, args.csv))
    print(f"{args.old} against {args.new or 'the working tree'}:")
    print(summary(rows))
    return rows


if __name__ == "__main__":
    main()
