import importlib.util
import re
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from corpus import corpus as corpus_dir
from corpus import corpus_root

matplotlib.use("Agg")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)

# Real recordings made by others live beside the project, not in it (tests/corpus.py: OPTCAL_CORPUS, else the
# shared folder beside the clone). REAL_DATA is that folder, present or not; a test that reads it asks for the
# ``corpus`` fixture (or calls corpus.corpus), which skips it when the folder is absent.
REAL_DATA = corpus_root()


@pytest.fixture(scope="session")
def corpus():
    """The real corpus's folder; the test is skipped (one reason, tests/corpus.py) when it is absent."""
    return corpus_dir()


def pytest_runtest_setup(item):
    """A test that asks for the corpus (directly, through a fixture or ``usefixtures``) is skipped here, before
    its fixtures, where the corpus is absent: raised outside a fixture, the skip keeps the location of
    tests/corpus.py, so ``pytest -rs`` folds every such skip into one line."""
    if "corpus" in item.fixturenames:
        corpus_dir()


@pytest.fixture(scope="session")
def computed_once(tmp_path_factory, worker_id):
    """``computed_once(name, make)``: the folder ``make(folder)`` filled, made once for the whole session,
    whichever xdist worker asks first (a file lock in the session's shared temporary folder; the pattern
    pytest-xdist documents for session fixtures). A module fixture that runs a study would otherwise run once
    on each worker that gets one of the module's tests."""
    from filelock import FileLock

    root = tmp_path_factory.getbasetemp()
    if worker_id != "master":
        root = root.parent  # the folder every worker's own temporary folder sits in

    def get(name: str, make):
        folder = root / f"once-{name}"
        with FileLock(str(folder) + ".lock"):
            if not (folder / ".complete").exists():
                folder.mkdir(exist_ok=True)
                make(folder)
                (folder / ".complete").touch()
        return folder

    return get


# The noise report's counts, levels and slopes; every other number's key names its unit (docs/noise.md)
UNITLESS_NOISE_KEYS = {"n_samples", "ci_level", "edf", "local_slope"}


def assert_numbers_carry_units(obj, unit: re.Pattern, unitless=UNITLESS_NOISE_KEYS, keys=()) -> None:
    """Every number in the JSON-like ``obj`` sits under a key that ``unit`` matches (its unit as a suffix) or
    one of ``unitless``; ``value``, ``low`` and ``high`` (an estimate and its interval) take their parent's."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            assert_numbers_carry_units(v, unit, unitless, (*keys, k))
    elif isinstance(obj, list):
        for v in obj:
            assert_numbers_carry_units(v, unit, unitless, keys)
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        named = [k for k in keys if k not in {"value", "low", "high"}]
        assert unit.search(named[-1]) or named[-1] in unitless, keys


def run_cli(argv, capsys):
    """optcal's command line in this process (arguments turned into strings): exit code, stdout, stderr."""
    from optcal.app.cli import main

    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def doc_script(name: str):
    """The script ``docs/scripts/<name>.py`` as a module (the tests check the figures and tables it makes)."""
    path = Path(__file__).resolve().parents[1] / "docs" / "scripts" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
