"""How much the value moves with the grid: the same scenes at resolutions 48, 96 and 192.

Run ``python validation/resolution.py`` (a few minutes).  Writes
``resolution.csv`` beside this file and prints, per scene, the values and
their relative spread between resolutions 96 and 192.  The refined value
should not depend on the grid; where it does, the grid led the refinement to
different local geodesics (see docs/record.md, *Known limitations*).
"""

from __future__ import annotations

import os
import sys

import numpy as np
from study import write_csv

import direct

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
from conftest import random_crossing_scene  # noqa: E402


def scenes():
    out = {name: direct.scenes.get(name) for name in ("fig2", "waves", "loop")}
    for seed in range(6):
        out[f"random{seed}"] = random_crossing_scene(seed, n_vert=8, min_crossings=2, max_crossings=8)
    eight = direct.scenes.get("fig10").components[0]
    for k in (0, 37, 64):
        c = direct.Component(np.roll(eight.reference, -k, axis=0), np.roll(eight.deformed, -k, axis=0), closed=True)
        out[f"fig10, first vertex {k}"] = direct.Scene((c,))
    return out


def main():
    rows = []
    for name, sc in scenes().items():
        vals = {r: direct.penalty(sc, resolution=r) for r in (48, 96, 192)}
        spread = abs(vals[192].value - vals[96].value) / vals[192].value
        for r, res in vals.items():
            rows.append(dict(scene=name, resolution=r, value=res.value, error_estimate=res.error_estimate,
                             seconds=res.seconds))
        values = "  ".join(f"{vals[r].value:.7f}" for r in (48, 96, 192))
        print(f"{name:24s} {values}  spread 96/192 {spread:.1e}", flush=True)
    write_csv(rows, os.path.join(HERE, "resolution.csv"))


if __name__ == "__main__":
    main()
