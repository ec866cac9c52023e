"""Names a package loads at first use (PEP 562), so that importing it imports nothing heavy: ``optcal`` (the front
door, whose ``import optcal`` and ``optcal --help`` import no NumPy) and ``optcal.core.gyro`` (whose simulator a
command that reads and fits a gyroscope never needs)."""

from __future__ import annotations

import importlib
import sys


def lazy_names(package: str, where: dict[str, str], exported) -> tuple:
    """The module functions ``__getattr__`` and ``__dir__`` of ``package``: a name of ``where`` (name -> module,
    relative to the package) is imported from its module when first looked up and kept in the package."""

    def __getattr__(name: str):
        if name in where:
            value = getattr(importlib.import_module(f"{package}.{where[name]}"), name)
            setattr(sys.modules[package], name, value)
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(exported))

    return __getattr__, __dir__
