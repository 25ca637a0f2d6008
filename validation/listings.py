"""The same scene listed in other ways: do the values agree, and does each value's estimate reach the others' bounds?

Run ``python validation/listings.py`` (about ten minutes).  The scenes are those of
``listings_scenes.json`` beside this file: pieces of ``M x M`` with a circle (tori, a cylinder) on which
adversarial reviews found values too high by more than their estimates, without a warning, for some
listings (docs/record.md, *Known limitations*).  Each scene runs as given, with its two components swapped, with
both vertex lists of every component reversed, and with every closed component started from the middle of
its vertex list (``np.roll`` of reference and deformed alike).  None of these changes ``J``.

There is no reference value: the proof is the ``upper_bound`` (the exact length of the returned curves,
so at least ``J``) of another run of the scene, any listing at any of its settings.  A run whose ``value -
error_estimate`` lies above another's ``upper_bound`` is too high by more than its estimate: ``SILENT``
without a ``ToleranceWarning``, ``warned`` with one.  Writes ``listings.csv`` beside this file (one row
per scene, setting and listing) and prints each scene's spread and verdicts.  ``--rev REV`` runs the
``direct`` of a git revision instead (a temporary worktree) and writes ``listings_REV.csv``.
"""

from __future__ import annotations

import csv
import json
import os
import time
import warnings

import numpy as np

import direct

HERE = os.path.dirname(os.path.abspath(__file__))


def listings(components: list[dict]) -> dict:
    """``{label: components}``: the scene as given, swapped, reversed and rolled (see the module docstring)."""

    def reversed_(c):
        return dict(c, reference=c["reference"][::-1], deformed=c["deformed"][::-1])

    def rolled(c):
        k = len(c["reference"]) // 2 if c["closed"] else 0
        return dict(c, reference=np.roll(c["reference"], -k, 0).tolist(),
                    deformed=np.roll(c["deformed"], -k, 0).tolist())

    return {"given": components, "swapped": components[::-1], "reversed": [reversed_(c) for c in components],
            "rolled": [rolled(c) for c in components]}


def solve(components: list[dict], setting: dict) -> dict:
    scene = direct.Scene.from_dict({"components": components})
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = direct.penalty(scene, **setting)
    warned = any(issubclass(w.category, direct.ToleranceWarning) for w in caught)
    return dict(value=res.value, estimate=res.error_estimate, upper_bound=res.upper_bound, warned=warned,
                seconds=time.perf_counter() - t0)


def main(out: str = "listings.csv") -> list[dict]:
    with open(os.path.join(HERE, "listings_scenes.json")) as f:
        scenes = json.load(f)["scenes"]
    rows = []
    for sc in scenes:
        runs = {json.dumps(setting): {label: solve(comps, setting)
                                      for label, comps in listings(sc["components"]).items()}
                for setting in sc["settings"]}
        # every run's upper_bound bounds J, whatever its setting
        bounds = {(st, label): r["upper_bound"] for st, found in runs.items() for label, r in found.items()}
        least_bound = min(bounds.values())
        for st, found in runs.items():
            for label, r in found.items():
                # how far value - estimate lies above the least upper bound of the other runs (relative)
                others = min(b for key, b in bounds.items() if key != (st, label))
                excess = (r["value"] - r["estimate"] - others) / others
                verdict = "ok" if excess <= 0 else ("warned" if r["warned"] else "SILENT")
                rows.append(dict(scene=sc["name"], setting=st, listing=label, value=r["value"],
                                 estimate=r["estimate"], relative_estimate=r["estimate"] / r["value"],
                                 upper_bound=r["upper_bound"],
                                 above_least_bound=(r["value"] - least_bound) / least_bound,
                                 excess_over_others=excess, warned=r["warned"], seconds=r["seconds"], verdict=verdict))
            values = [r["value"] for r in found.values()]
            verdicts = {label: row["verdict"] for label, row in zip(found, rows[-len(found):])}
            print(f"{sc['name']:18s} {st:40s} values {min(values):.9f} .. {max(values):.9f} "
                  f"(spread {(max(values) - min(values)) / min(values):.1e}), largest estimate "
                  f"{max(r['estimate'] / r['value'] for r in found.values()):.1e}; "
                  + ", ".join(f"{k} {v}" for k, v in verdicts.items()), flush=True)
    with open(os.path.join(HERE, out), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"{sum(r['verdict'] == 'SILENT' for r in rows)} of {len(rows)} rows SILENT, "
          f"{sum(r['verdict'] == 'warned' for r in rows)} warned over the others' bounds")
    return rows


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", help="run the direct of this git revision (a temporary worktree)")
    args = ap.parse_args()
    if args.rev:
        from ab import at_revision

        at_revision(args.rev, f"import listings as m; m.main(out={'listings_' + args.rev + '.csv'!r})")
    else:
        main()
