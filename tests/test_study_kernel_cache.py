"""The kernel-cache check (optcal/core/kernels/cache.py) recognises a cache built by any command (issue #22): after
a plain `pip install -e .` a command that compiled only the batch and Jacobian entry points (a least-squares
fit, a study's workers) left no cost_one index, and every later command warned that it was compiling."""

from __future__ import annotations

import sys

from optcal.core.kernels import cache


def _tree(tmp_path, monkeypatch, names):
    pkg = tmp_path / "kernels"
    (pkg / "__pycache__").mkdir(parents=True)
    for n in names:
        (pkg / "__pycache__" / n).write_bytes(b"")
    monkeypatch.setattr(cache, "__file__", str(pkg / "cache.py"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "none"))
    monkeypatch.setattr(cache.Path, "home", lambda: tmp_path)


def test_any_cached_entry_point_of_this_python_counts(tmp_path, monkeypatch):
    tag = f"py{sys.version_info.major}{sys.version_info.minor}"
    _tree(tmp_path, monkeypatch, [f"evaluate.evaluate_batch-197.{tag}.nbi", f"evaluate.jacobian-226.{tag}.nbi"])
    assert cache.is_cold() is False


def test_another_pythons_cache_or_another_modules_does_not(tmp_path, monkeypatch):
    _tree(tmp_path, monkeypatch, ["evaluate.evaluate_batch-197.py27.nbi", "_terms.forward_all-38.py311.nbi"])
    assert cache.is_cold() is True
