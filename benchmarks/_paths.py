"""Where a module lives at the commit asv installed. Since issue #30 optcal's modules sit in optcal.core,
optcal.solvers, optcal.studies and optcal.app; before, in optcal, solvers and studies. The suite names each
module by its path now and falls back to the old one, so that it runs unchanged over the whole history."""

from __future__ import annotations

import importlib

# the path now -> the path before the move
BEFORE = (("optcal.core.", "optcal."), ("optcal.solvers", "solvers"), ("optcal.studies", "studies"))


def module(name: str):
    """The module ``name``, or where it was before the move when this commit predates it."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError:
        for now, before in BEFORE:
            if name == now.rstrip(".") or name.startswith(now):
                return importlib.import_module(before + name[len(now):])
        raise
