"""What Newton's damping beside kinks and the extra round after a stalled one cost and give, on two closed curves.

Run ``python validation/closed_rules.py`` (about a minute alone).  Two scenes of ``listings_scenes.json``, as
given: ``nested_318`` (two nested random polygons, no crossing, ``G`` at ``tol=1e-4``) and ``nested_8_16_g``
(an 8-gon nested in a 16-gon, ``g`` with ``p = 2`` at ``tol=1e-3``).  Each runs in this one process with the
two rules of :mod:`direct.refinement` switched off and on in turn (``_KINK_SOLVES`` 0 or its value,
``_STALL_RATIO`` 0 or its value: docs/record.md, *A closed curve's Newton held to a ten-thousandth of its
steps by one kink*), and prints the value, its estimate and the time of each.  Writes ``closed_rules.csv``
beside this file.
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings

import direct
from direct import refinement

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from listings import listings  # noqa: E402
from study import write_csv  # noqa: E402

CASES = (("nested_318", dict(metric="G", tol=1e-4)), ("nested_8_16_g", dict(metric="g", power=2, tol=1e-3)))


def main() -> None:
    with open(os.path.join(HERE, "listings_scenes.json")) as fh:
        scenes = {s["name"]: s["components"] for s in json.load(fh)["scenes"]}
    solves, stall = refinement._KINK_SOLVES, refinement._STALL_RATIO
    rows = []
    try:
        for name, kwargs in CASES:
            scene = direct.Scene.from_dict({"components": listings(scenes[name])["given"]})
            for kinks, stalled in ((False, False), (True, False), (False, True), (True, True)):
                refinement._KINK_SOLVES = solves if kinks else 0
                refinement._STALL_RATIO = stall if stalled else 0.0
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always", direct.ToleranceWarning)
                    start = time.perf_counter()
                    res = direct.penalty(scene, **kwargs)
                rows.append(dict(scene=name, settings=json.dumps(kwargs), kink_damping=kinks, stall_round=stalled,
                                 value=res.value, error_estimate=res.error_estimate, warned=bool(caught),
                                 seconds=round(time.perf_counter() - start, 2)))
                print(rows[-1], flush=True)
    finally:
        refinement._KINK_SOLVES, refinement._STALL_RATIO = solves, stall
    write_csv(rows, os.path.join(HERE, "closed_rules.csv"))


if __name__ == "__main__":
    main()
