"""Where the real corpus lives: recordings other people made on real sensors, kept beside the project and never
in it (issue #28). The one rule, for the tests, the benchmarks and the doc scripts alike: the folder named by
``OPTCAL_CORPUS`` if that variable is set, else ``../shared/data/real`` from the repository's root. The folder's
own README gives each recording's source, licence and MD5.

A test that needs the corpus asks for it through ``corpus(*parts)`` (or the ``corpus`` fixture of
tests/conftest.py, which calls it): where the folder is absent (a plain clone, or ``OPTCAL_CORPUS`` naming no
folder) the test is skipped, with one reason raised from one line so that ``pytest -rs`` prints it once.
Standard library only: the doc scripts import it too (``sys.path`` given ``tests/``)."""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ENV = "OPTCAL_CORPUS"
DEFAULT = "../shared/data/real"  # from the repository's root: the shared folder beside the clone
REASON = f"the real corpus is absent: set {ENV} to its folder (default {DEFAULT} beside the clone)"


def corpus_root() -> Path:
    """The corpus's folder, whether it exists or not: ``$OPTCAL_CORPUS`` if set, else the default."""
    env = os.environ.get(ENV)
    return Path(env).expanduser() if env else (ROOT / DEFAULT).resolve()


def corpus_present() -> bool:
    return corpus_root().is_dir()


def corpus(*parts: str) -> Path:
    """A path inside the corpus; skips the calling test when the corpus is absent."""
    root = corpus_root()
    if not root.is_dir():
        import pytest

        pytest.skip(REASON)
    return root.joinpath(*parts)
