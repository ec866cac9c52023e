"""A third-party module imported at its first use, so that importing the registry (every solver module) stays
light: CasADi costs about 0.1 s to import and NLopt a few hundredths, in every command, whether or not it runs
those solvers."""

from __future__ import annotations

import importlib


class LazyModule:
    """Stands for module ``name`` in ``namespace`` (a solver module's ``globals()``) under ``alias``; the first
    attribute looked up imports the module and puts it in the namespace in this object's place."""

    def __init__(self, name: str, namespace: dict, alias: str):
        self._name, self._namespace, self._alias = name, namespace, alias

    def __getattr__(self, attr: str):
        module = importlib.import_module(self._name)
        self._namespace[self._alias] = module
        return getattr(module, attr)
