"""Scheme files (docs/planning.md, "For a person: fixtures, faces and tilts, order, files, figure"): a planned (or
any) scheme as CSV, read wherever a scheme name is.

Comment lines start with ``#`` (the planner writes what it planned there). The header names the columns;
``dx, dy, dz`` are required: the unit specific-force direction of each position in the sensor frame
(dimensionless; A = g_local·d). ``position``, ``face_down``, ``alpha_deg`` and ``beta_deg`` (how a person
places it, :mod:`optcal.core.plan.fixtures`) are written for people and ignored on reading.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.plan.fixtures import to_faces

REQUIRED = ("dx", "dy", "dz")
UNIT_TOL = 1e-3  # a direction must be a unit vector to this much (six decimals written)


def read_scheme(path: str | Path) -> np.ndarray:
    p = Path(path)
    if not p.is_file():
        raise InputError(f"scheme file {str(p)!r} not found; give a CSV written by optcal plan -o, or a scheme name")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"scheme file {str(p)!r} cannot be read as UTF-8 text ({type(exc).__name__}); "
                         "give a CSV with columns dx, dy, dz") from None
    rows = list(csv.reader(line for line in io.StringIO(text) if line.strip() and not line.lstrip().startswith("#")))
    if not rows:
        raise InputError(f"scheme file {str(p)!r} has no header and no positions; it needs columns dx, dy, dz")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputError(f"scheme file {str(p)!r} lacks column(s) {', '.join(missing)}; a scheme file has the unit "
                         "direction of each position in columns dx, dy, dz")
    cols = [header.index(c) for c in REQUIRED]
    out = []
    for k, row in enumerate(rows[1:], start=2):
        try:
            v = [float(row[c]) for c in cols]
        except (IndexError, ValueError):
            raise InputError(f"scheme file {str(p)!r}, data row {k - 1}: dx, dy, dz must be three numbers") from None
        out.append(v)
    d = np.array(out, float).reshape(-1, 3)
    if len(d) == 0:
        raise InputError(f"scheme file {str(p)!r} has a header but no positions")
    norm = np.linalg.norm(d, axis=1)
    bad = np.flatnonzero(~np.isfinite(norm) | (np.abs(norm - 1.0) > UNIT_TOL))
    if bad.size:
        raise InputError(f"scheme file {str(p)!r}, data row {int(bad[0]) + 1}: (dx, dy, dz) has length "
                         f"{norm[bad[0]]:.6g}, not 1; directions must be unit vectors")
    return d / norm[:, None]


def scheme_csv(directions: np.ndarray, comments: list[str] = ()) -> str:
    """The CSV text of a scheme, positions in the given order."""
    d = np.asarray(directions, float)
    faces, a, b = to_faces(d)
    lines = [f"# {c}" for c in comments]
    lines.append("position,dx,dy,dz,face_down,alpha_deg,beta_deg")
    lines += [f"{i + 1},{x:.9f},{y:.9f},{z:.9f},{f},{aa:.2f},{bb:.2f}"
              for i, ((x, y, z), f, aa, bb) in enumerate(zip(d, faces, a, b))]
    return "\n".join(lines) + "\n"
