"""What optcal printed and wrote before a change that must not alter it (issue #30: the layers' move "changes
nothing a user sees"): calibrations of every corpus recording, the IMU fits, a study's trials and a figure's
pixels, kept in ``tests/golden/outputs.json`` and compared value by value (relative 1e-12, so a different
summation order in BLAS is not a failure, a different answer is).

The tests that already compute these outputs call ``check(key, value)`` (or assert that ``differences(key,
value)`` is empty); nothing is computed twice. A change
that means to alter an output regenerates the file, serially, and says why in its commit:

    OPTCAL_GOLDEN=write .venv/bin/python -m pytest -p no:xdist tests/test_corpus_wild.py tests/test_study_api.py \\
        tests/test_same_outputs.py

Standard library and NumPy only."""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path

FILE = Path(__file__).resolve().parent / "golden" / "outputs.json"
RTOL = 1e-12


def _load() -> dict:
    return json.loads(FILE.read_text()) if FILE.is_file() else {}


def _plain(value):
    """JSON-ready: NumPy arrays and scalars as lists and floats, dict keys as strings."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _same(a, b, path: str) -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys {sorted(set(a) ^ set(b))} differ"]
        return [m for k in a for m in _same(a[k], b[k], f"{path}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: length {len(a)} != {len(b)}"]
        return [m for i, (x, y) in enumerate(zip(a, b)) for m in _same(x, y, f"{path}[{i}]")]
    if isinstance(a, float) or isinstance(b, float):
        if isinstance(a, (int, float)) and isinstance(b, (int, float)):
            if (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=RTOL, abs_tol=0.0):
                return []
        return [f"{path}: {a!r} != {b!r}"]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def differences(key: str, value) -> list[str]:
    """What differs between ``value`` and what ``key`` held before (empty: the same); with
    ``OPTCAL_GOLDEN=write``, record ``value`` instead and report nothing."""
    value = _plain(value)
    if os.environ.get("OPTCAL_GOLDEN") == "write":
        data = _load()
        data[key] = value
        FILE.parent.mkdir(exist_ok=True)
        FILE.write_text(json.dumps(dict(sorted(data.items())), indent=1) + "\n")
        return []
    data = _load()
    if key not in data:
        return [f"no golden value for {key!r}: regenerate tests/golden/outputs.json (tests/golden.py)"]
    return _same(value, data[key], key)


def check(key: str, value) -> None:
    """Assert that ``value`` is what ``key`` held before (:func:`differences`, the first five named)."""
    diffs = differences(key, value)
    more = f" … ({len(diffs) - 5} more)" if len(diffs) > 5 else ""
    assert not diffs, "output changed: " + "; ".join(diffs[:5]) + more


def pixels(png: Path) -> str:
    """SHA-256 of a PNG's decoded pixels (not its bytes, which carry the writer's version)."""
    import matplotlib.image

    arr = matplotlib.image.imread(str(png))
    return hashlib.sha256(arr.tobytes()).hexdigest() + f" {arr.shape}"
