"""What the validation studies share: writing their rows to a CSV file."""

from __future__ import annotations

import csv
import os


def write_csv(rows: list[dict], path: str | os.PathLike) -> None:
    """Write ``rows`` (dicts with the same keys, in order) to ``path``, one header line then one line per row."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
