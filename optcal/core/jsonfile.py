"""Reading a JSON object from a file a user gave, with one-line errors (docs/design.md, "File formats"): the one reader
behind presets, truths, calibration files, noise analyses, intervals and imported calibrations; and the one
writer of the calibration files (accelerometer and IMU), which keeps an existing file unless told and replaces
one whole or not at all (:mod:`optcal.core.atomicfile`)."""

from __future__ import annotations

from pathlib import Path

from optcal.core.errors import InputError


def read_json_object(path, what: str) -> dict:
    """The JSON object in ``path``; an :class:`InputError` naming ``what`` the file should hold (e.g. "presets")
    when it cannot be read, is not JSON, or holds something other than an object."""
    try:
        text = Path(path).read_text()
    except UnicodeDecodeError:
        raise InputError(f"{what} file {path} is not text (a JSON {what} file was expected)") from None
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {exc.strerror or exc}") from None
    return parse_json_object(text, path, what)


def parse_json_object(text: str, path, what: str) -> dict:
    """:func:`read_json_object` for text already read."""
    import json  # here: a command that reads and writes no JSON does not import it

    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{what} {path} is not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(obj, dict):
        raise InputError(f"{what} {path} must be a JSON object")
    return obj


def write_json_object(obj: dict, path, *, overwrite: bool = False) -> None:
    """Write ``obj`` as indented JSON through a temporary file renamed into place (:mod:`optcal.core.atomicfile`);
    an existing file is kept unless ``overwrite`` (the CLI's ``--force``). One-line :class:`InputError` for
    both."""
    import json

    from optcal.core.atomicfile import EXISTS, write_atomic

    path = Path(path)
    if path.exists() and not overwrite:  # before rendering, as ever
        raise InputError(EXISTS.format(path=path))
    write_atomic(path, json.dumps(obj, indent=2) + "\n", overwrite=overwrite)
