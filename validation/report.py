"""Regenerate ``validation/REPORT.md`` in one command (issue 5, item 5).

Usage::

    python validation/report.py            # the full study (several minutes)
    python validation/report.py --quick    # fewer scenes and settings (a few minutes at most)

It writes ``validation/REPORT.md`` and, through the study modules, every
figure and CSV the report links to (``validation/*.png``, ``validation/*.csv``).
Sections, in this order, each produced by a module of ``validation/`` with the
signature ``report(outdir, quick=False) -> str`` (markdown):

1. ``phasefield_study``: the phase-field solver against the oracle (eps, grid step, rates);
2. ``pareto``: speed against accuracy, both methods, Pareto fronts;
3. ``failures``: where each method fails.

A module that is missing or raises is reported in its section with the
traceback summary, the other sections still run, and the command exits with
status 1 at the end.  So does a figure linked from a section that this run
did not write (missing, or older than the run).
"""

from __future__ import annotations

import argparse
import datetime
import importlib
import os
import platform
import re
import subprocess
import sys
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
if HERE not in sys.path:
    sys.path.insert(0, HERE)

SECTIONS = [
    ("phasefield_study", "The phase-field solver against the oracle"),
    ("pareto", "Speed against accuracy"),
    ("failures", "Where each method fails"),
]


def _git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                             timeout=10)
        if out.returncode != 0:
            return "unavailable"
        commit = out.stdout.strip()
        # the code, not the outputs this command rewrites
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", "*.py", "pyproject.toml"],
                               cwd=ROOT, capture_output=True, text=True, timeout=10)
        if dirty.returncode == 0 and dirty.stdout.strip():
            commit += " (with uncommitted changes to the code)"
        return commit
    except (OSError, subprocess.SubprocessError):
        return "unavailable"


def _versions() -> str:
    parts = [f"Python {platform.python_version()}"]
    for mod in ("numpy", "scipy", "matplotlib"):
        try:
            parts.append(f"{mod} {importlib.import_module(mod).__version__}")
        except Exception:
            parts.append(f"{mod} (not importable)")
    try:
        import direct

        parts.append(f"direct {direct.__version__}")
    except Exception:
        parts.append("direct (not importable)")
    return ", ".join(parts)


INTRO = r"""## The two methods

**The penalty.**  For a deformation `phi` of a body `M` (intervals and circles) with reference
embedding `j`, the self-contact penalty `J(phi)` (paper, section 3, eq. (9)) is the least length, in
a metric on `M x M` that degenerates where `phi(x1) = phi(x2)`, of a family of curves whose boundary
in the interior of `M x M` minus the diagonal is the set of signed self-crossings `r_phi^{-1}(0)`.
Metric `G`: `G(y1, y2) = |y1 - y2|^4 Id` (Example 14), i.e. `dl = |r_phi|^2 ||dx||_B` with
`B = diag(|phi'(x1)|^2, |phi'(x2)|^2)`; metric `g`: `g(s) = s^2`.  All numbers below are for `G`
and for the whole of `M x M` (both points `(x1, x2)` and `(x2, x1)` of each crossing).

**Direct method (section 5.1.1), the package `direct`, used here as the oracle.**  Find the
crossings and their signs; compute the geodesic distances `A_ij` between the positive and negative
crossing points and `A_i0`, `A_0j` to the boundary of `M x M` minus the diagonal (grid Dijkstra on
each pair domain, then continuous refinement of each geodesic to a relative tolerance `tol`, with a
Richardson error estimate); solve the assignment program (34)-(36).  `direct.penalty(scene,
tol=...)` returns the value, an error estimate and the grid-only value.

**Phase-field method (section 5.1.2), `validation/phasefield.py`.**  Minimize over a phase `u` on
`M x M` minus the diagonal

    L_eps(u) = int ( eps (Phi_phi - grad u)^T A^{-1} (Phi_phi - grad u)
                     + R(u - theta_phi + theta_j) / eps ) sqrt(det A) dx,

with `Phi_phi = grad theta_phi - grad theta_j`, `A` the metric above and `R` a `2 pi`-periodic well
(`R(t) = 1 - cos t` here).  By Prop. 31, `L_eps` Gamma-converges to `beta` times the length of the
jump set of `u`, so `J_eps = inf L_eps` satisfies `J_eps / beta -> J` as `eps -> 0`, with
`beta = int_0^{2 pi} 2 sqrt(R) = 8 sqrt 2` for this `R`; the level sets
`u - (theta_phi - theta_j) = pi (mod 2 pi)` approximate the optimal curves.  The solver discretizes
each pair domain on a grid of `n` cells along its longer side and returns `J_eps / beta`, which
is the quantity compared with the oracle's `J` throughout.
"""


def _run_section(modname: str, title: str, outdir: str, quick: bool) -> tuple[str, bool, float]:
    """``(markdown, ok, seconds)`` of one section; a missing or failing module gives a failure section."""
    t0 = time.perf_counter()
    try:
        mod = importlib.import_module(modname)
        fn = mod.report
        md = fn(outdir, quick)
        if not isinstance(md, str):
            raise TypeError(f"{modname}.report returned {type(md).__name__}, expected str (markdown)")
        return md, True, time.perf_counter() - t0
    except BaseException as exc:  # noqa: BLE001 - the report must say what went wrong, whatever it was
        if isinstance(exc, KeyboardInterrupt):
            raise
        dt = time.perf_counter() - t0
        frames = [f for f in traceback.extract_tb(exc.__traceback__)
                  if "importlib" not in f.filename and not f.filename.startswith("<frozen")]
        summary = "".join(traceback.format_list(frames[-4:])) + "".join(traceback.format_exception_only(type(exc), exc))
        if isinstance(exc, ModuleNotFoundError) and exc.name == modname:
            what = f"the module `validation/{modname}.py` is missing"
        else:
            what = f"`validation/{modname}.py` raised `{type(exc).__name__}`"
        md = (f"## {title}\n\n**This section failed: {what}.**  Its figures and tables are absent from this "
              f"report; `report.py` exits with status 1.\n\nTraceback (last frames):\n\n```\n{summary.rstrip()}\n```\n")
        print(f"[report] section {modname} FAILED: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
        return md, False, dt


def build(outdir: str = HERE, quick: bool = False, out: str | None = None) -> bool:
    """Write ``REPORT.md`` into ``outdir`` (or ``out``); True if every section succeeded and wrote its figures."""
    t_start = time.perf_counter()
    started = datetime.datetime.now(datetime.timezone.utc)
    t_wall = time.time()
    os.makedirs(outdir, exist_ok=True)
    results = []
    for modname, title in SECTIONS:
        print(f"[report] section {modname} ...", file=sys.stderr, flush=True)
        md, ok, dt = _run_section(modname, title, outdir, quick)
        print(f"[report] section {modname}: {'ok' if ok else 'FAILED'} in {dt:.0f} s", file=sys.stderr, flush=True)
        results.append((modname, title, md, ok, dt))
    total = time.perf_counter() - t_start

    cmd = "python validation/report.py" + (" --quick" if quick else "")
    rel = os.path.relpath(outdir, ROOT) if os.path.abspath(outdir).startswith(ROOT) else outdir
    head = [
        "# The phase-field solver validated against the direct method",
        "",
        "This report compares the paper's two ways of computing the topological self-contact penalty "
        "`J(phi)` of plane curves (*contacts in dimension 2*, section 5.1): the direct method, "
        "implemented by the package `direct` and used as the oracle, and a phase-field solver "
        "(`validation/phasefield.py`).  It is generated; do not edit it by hand.",
        "",
        f"- **Regenerate with:** `{cmd}` from the repository root (a clean checkout with the package "
        "installed: `pip install -e .`).  Every figure and table below is produced by that command"
        + (" (`--quick`: fewer scenes and settings than the full run)." if quick else "."),
        f"- **Generated:** {started.strftime('%Y-%m-%d %H:%M UTC')}, git commit {_git_commit()}.",
        f"- **Machine:** {platform.platform()}, {platform.machine()}, {os.cpu_count()} CPUs reported by "
        f"`os.cpu_count()`; {_versions()}.",
        f"- **Total wall time of the run:** {total:.0f} s ("
        + ", ".join(f"{m}: {dt:.0f} s{'' if ok else ' (failed)'}" for m, _, _, ok, dt in results) + ").",
        f"- **Outputs:** `{rel}/` (figures linked relative to it).",
        "",
    ]
    failed = [m for m, _, _, ok, _ in results if not ok]
    # every figure the report links must have been written by this run
    bad_figs = []
    for m, _, md, _ok, _ in results:
        for link in re.findall(r"!\[[^\]]*\]\(([^)\s]+)", md):
            f = os.path.join(outdir, link)
            if not os.path.exists(f):
                bad_figs.append(f"`{link}` (from {m}: missing)")
            elif os.path.getmtime(f) < t_wall - 1:
                bad_figs.append(f"`{link}` (from {m}: not rewritten by this run)")
    if bad_figs:
        head += [f"**Figures linked below but not produced by this run: {', '.join(bad_figs)}.**", ""]
        print(f"[report] FIGURES NOT PRODUCED: {', '.join(bad_figs)}", file=sys.stderr, flush=True)
    if failed:
        head += [f"**Incomplete report: {len(failed)} of {len(SECTIONS)} sections failed "
                 f"({', '.join(failed)}); see their sections below.**", ""]
    head += ["## Contents", ""]
    head += [f"{k + 1}. {title} (`validation/{m}.py`, {dt:.0f} s){'' if ok else ' - FAILED'}"
             for k, (m, title, _, ok, dt) in enumerate(results)]
    head += [""]
    body = [INTRO]
    for m, title, md, ok, dt in results:
        if not md.lstrip().startswith("#"):
            md = f"## {title}\n\n{md}"
        body.append(md.rstrip() + "\n")
        body.append(f"*Section generated by `validation/{m}.py` in {dt:.0f} s.*\n" if ok else
                    f"*Section attempted with `validation/{m}.py`: failed after {dt:.0f} s.*\n")
    text = "\n".join(head) + "\n" + "\n".join(body)
    path = out or os.path.join(outdir, "REPORT.md")
    with open(path, "w") as fh:
        fh.write(text)
    status = "all sections ok" if not failed else "FAILED: " + ", ".join(failed)
    print(f"[report] wrote {path} in {total:.0f} s; {status}", file=sys.stderr, flush=True)
    return not failed and not bad_figs


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="regenerate validation/REPORT.md (issue 5)")
    p.add_argument("--quick", action="store_true", help="fewer scenes and settings in every section")
    p.add_argument("--outdir", default=HERE, help="where REPORT.md, figures and CSVs go (default: validation/)")
    a = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    return 0 if build(a.outdir, a.quick) else 1


if __name__ == "__main__":
    sys.exit(main())
