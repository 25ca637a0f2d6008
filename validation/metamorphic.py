"""Metamorphic relations on random interval scenes, beyond the test suite.

Run ``python validation/metamorphic.py`` (about a minute).  For 30
random scenes (2 or 3 polylines of 7 vertices, 1 to 10 crossings) it compares
``J`` with ``J`` after a rigid motion, after inserting a vertex and after
reversing a component, all of which leave ``J`` unchanged, and prints the
cases where the change exceeds three times the error estimate (or 1e-3).
Writes ``metamorphic.csv`` beside this file.
"""

from __future__ import annotations

import os
import sys

import numpy as np
from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import insert_vertex, rigid, study_scenes  # noqa: E402


def main(seeds=range(100, 130)):
    rows, bad = [], []
    for seed, sc in study_scenes(seeds):
        base = direct.penalty(sc)
        rng = np.random.default_rng(seed)
        k = int(rng.integers(len(sc.components)))
        comp = sc.components[k]
        variants = {"rigid motion": rigid(sc, rng.uniform(0, 6), rng.normal(size=2))}
        comps = list(sc.components)
        comps[k] = insert_vertex(comp, int(rng.integers(comp.n_segments)), float(rng.uniform(0.1, 0.9)))
        variants["vertex inserted"] = direct.Scene(tuple(comps))
        comps = list(sc.components)
        comps[k] = comp.reversed()
        variants["component reversed"] = direct.Scene(tuple(comps))
        allowed = 3 * max(base.error_estimate, 1e-3 * base.value)
        for name, variant in variants.items():
            v = direct.penalty(variant).value
            rel = abs(v - base.value) / base.value
            rows.append(dict(seed=seed, crossings=len(base.crossings), relation=name, J=base.value, J_variant=v,
                             relative_change=rel, relative_estimate=base.error_estimate / base.value))
            if abs(v - base.value) > allowed:
                bad.append(rows[-1])
    write_csv(rows, os.path.join(HERE, "metamorphic.csv"))
    worst = max(rows, key=lambda r: r["relative_change"])
    print(f"{len(rows)} comparisons on {len(rows) // 3} scenes; largest relative change {worst['relative_change']:.1e} "
          f"(seed {worst['seed']}, {worst['relation']})")
    print(f"beyond 3 x error estimate (or 1e-3): {len(bad)}")
    for r in bad:
        print(f"  seed {r['seed']} {r['relation']}: J = {r['J']:.7g} -> {r['J_variant']:.7g} "
              f"({r['relative_change']:.1e}, estimate {r['relative_estimate']:.1e})")


if __name__ == "__main__":
    main()
