"""Accuracy of `direct` on cases with a known value, against the tolerance.

Run ``python validation/convergence.py``: writes ``convergence.csv`` and
``convergence.png`` beside this file and prints a markdown table.  References:
closed forms for the right angle, shared/NUMERICS.md at 60 degrees, and
``tests/references.py`` (the eikonal ODE of a straight crossing, integrated
independently of ``direct``) at other angles and uneven arm lengths.  Each row is
one call of ``direct.penalty`` (wall time measured in this process; compare
the ratios, the machines are shared).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from references import crossing_reference  # noqa: E402  (eikonal ODE, independent of direct)

CROSS60_POINT = 0.2581226580725618  # shared/NUMERICS.md: eikonal ODE, two independent computations
ARMS = (0.7, 1.1, 0.5, 0.9)

CASES = [
    ("right angle, G", direct.scenes.cross(0.3, 0.5, 0.4, 0.6), "G", 2 * 0.3**3 / 3),
    ("right angle, g (p=2)", direct.scenes.cross(0.3, 0.5, 0.4, 0.6), "g", 2 * 0.3**5 / 5),
    ("60 degrees, G", direct.scenes.get("cross60"), "G", 2 * CROSS60_POINT),
    ("37 degrees, uneven arms, G", direct.scenes.cross(*ARMS, angle=np.radians(37)), "G",
     crossing_reference(np.radians(37), *ARMS)),
    ("124 degrees, uneven arms, g (p=2)", direct.scenes.cross(*ARMS, angle=np.radians(124)), "g",
     crossing_reference(np.radians(124), *ARMS, k=4)),
    ("1 degree (grazing), G", direct.scenes.cross(*ARMS, angle=np.radians(1)), "G",
     crossing_reference(np.radians(1), *ARMS)),
]
TOLS = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7]


def main() -> list[dict]:
    direct.penalty("cross")  # warm up imports and caches
    rows = []
    for name, scene, metric, exact in CASES:
        grid = direct.penalty(scene, metric, refine=False)
        rows.append(dict(case=name, method="grid Dijkstra (16 nbrs, 128 cells)", tol="", value=grid.value,
                         rel_error=abs(grid.value - exact) / exact, rel_estimate="", seconds=grid.seconds))
        for tol in TOLS:
            t0 = time.perf_counter()
            res = direct.penalty(scene, metric, tol=tol)
            dt = time.perf_counter() - t0
            rows.append(dict(case=name, method="refined", tol=tol, value=res.value,
                             rel_error=abs(res.value - exact) / exact, rel_estimate=res.error_estimate / exact,
                             seconds=dt))
    write_csv(rows, os.path.join(HERE, "convergence.csv"))
    _chart(rows)
    print("| case | tol | relative error | error_estimate / J | seconds |")
    print("|---|---|---|---|---|")
    for r in rows:
        tol = "grid only" if r["tol"] == "" else f"{r['tol']:.0e}"
        est = "" if r["rel_estimate"] == "" else f"{r['rel_estimate']:.1e}"
        print(f"| {r['case']} | {tol} | {r['rel_error']:.1e} | {est} | {r['seconds']:.3f} |")
    return rows


def _chart(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for name in dict.fromkeys(r["case"] for r in rows):
        ref = [r for r in rows if r["case"] == name and r["tol"] != ""]
        tol = np.array([r["tol"] for r in ref])
        err = np.maximum([r["rel_error"] for r in ref], 1e-16)
        est = np.array([r["rel_estimate"] for r in ref])
        line, = ax.loglog(tol, err, "o-", label=f"{name}: true error")
        ax.loglog(tol, np.maximum(est, 1e-16), "x--", color=line.get_color(), label=f"{name}: error_estimate")
        grid = [r for r in rows if r["case"] == name and r["tol"] == ""][0]
        ax.axhline(grid["rel_error"], color=line.get_color(), lw=0.8, ls=":")
    ax.loglog(TOLS, TOLS, "k-", lw=0.6, label="error = tol")
    ax.set_xlabel("tol")
    ax.set_ylabel("relative error of J")
    ax.set_title("direct.penalty against closed forms (dotted: grid Dijkstra alone)")
    ax.invert_xaxis()
    ax.legend(fontsize=6.5)
    fig.tight_layout()
    fig.savefig(os.path.join(HERE, "convergence.png"), dpi=120)


if __name__ == "__main__":
    main()
