"""CSV files of test points, read as rows and written back after an edit (simulated GCPs with
check points, sigmas or columns changed)."""
from __future__ import annotations

import csv
from pathlib import Path


def read_rows(path) -> list[dict]:
    """The data rows of the CSV ``path``, each a dict by column name."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def write_rows(path, rows: list[dict], columns: list[str] | None = None) -> Path:
    """``rows`` written to the CSV ``path``: ``columns`` (default: the first row's, in order) and no
    other. Returns the path."""
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns or list(rows[0]), extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    return Path(path)
