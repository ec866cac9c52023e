"""Small helpers shared by sub-commands: option parsing, JSON files, the parameter table."""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import InputError


def read_json_object(path: str, what: str) -> dict:
    try:
        obj = json.loads(Path(path).read_text())
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{what} {path} is not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(obj, dict):
        raise InputError(f"{what} {path} must be a JSON object")
    if isinstance(obj.get("parameters"), dict):  # a calibration file
        obj = obj["parameters"]
    return obj


def parse_options(items: list[str] | None) -> dict:
    """``KEY=VALUE`` pairs; values are parsed as JSON where they can be (numbers, true/false), else strings."""
    out = {}
    for item in items or []:
        if "=" not in item:
            raise InputError(f"--option {item!r} must be KEY=VALUE")
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out


def refuse_overwrite(path: str | None, force: bool) -> None:
    if path and Path(path).exists() and not force:
        raise InputError(f"{path} exists; choose another output path or pass --force to overwrite it")


def parameter_table(names, values, stderr=None, truth: dict | None = None) -> str:
    """A fixed-width table: name, estimate, standard error, and the truth and error in SEs when given."""
    import numpy as np

    head = f"{'parameter':<10} {'estimate':>16} {'std. error':>12}"
    if truth:
        head += f" {'truth':>16} {'error/SE':>9}"
    lines = [head, "-" * len(head)]
    for i, n in enumerate(names):
        se = None if stderr is None else stderr[i]
        se_txt = "unobservable" if se is None or not np.isfinite(se) else f"{se:12.3e}"
        row = f"{n:<10} {values[i]:16.9g} {se_txt:>12}"
        if truth and n in truth:
            err = values[i] - truth[n]
            z = f"{err / se:9.2f}" if se is not None and np.isfinite(se) and se > 0 else f"{'':>9}"
            row += f" {truth[n]:16.9g} {z}"
        lines.append(row)
    return "\n".join(lines)
