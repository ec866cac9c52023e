"""A study killed with SIGKILL (a real ``kill -9`` of a subprocess running ``optcal study run``) resumes
and loses nothing: the finished store has exactly one row per trial, identical to an uninterrupted run."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from optcal.studies import spec as S
from optcal.studies.execute import run_study
from optcal.studies.store import TIMING, Store

SPEC = """
name = "killme"
runs = 10
seed = 5
models = ["nonlinear12"]
schemes = ["24"]
tilt_deg = 1.0
budget = 3000
[navigation]
enabled = false
[[solvers]]
name = "scipy-lm"
[[solvers]]
name = "staged:scipy-lm"
"""


def _stored(db: Path) -> int:
    if not db.exists():
        return 0
    try:
        con = sqlite3.connect(db, timeout=1.0)
        try:
            return con.execute("SELECT COUNT(*) FROM trials").fetchone()[0]
        finally:
            con.close()
    except sqlite3.OperationalError:  # the table does not exist yet
        return 0


def _rows(folder):
    with Store.open_existing(folder) as st:
        return [{k: v for k, v in r.items() if k not in TIMING} for r in st.rows()]


def test_kill_minus_9_then_resume_loses_nothing(tmp_path):
    spec_path = tmp_path / "killme.toml"
    spec_path.write_text(SPEC)
    out = tmp_path / "killed"
    db = out / "study.sqlite"
    cmd = [sys.executable, "-m", "optcal.app.cli", "study", "run", str(spec_path), "--out", str(out),
           "--executor", "serial", "--no-report", "--no-progress"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while _stored(db) < 4 and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert proc.poll() is None, f"the study ended before it could be killed: {proc.stderr.read()!r}"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    n_killed = _stored(db)
    assert 4 <= n_killed < 20, n_killed

    # resume through the command line, as a user would
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert f"skipped {n_killed} already stored" in res.stdout

    con = sqlite3.connect(db)
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    ids = [r[0] for r in con.execute("SELECT trial_id FROM trials")]
    con.close()
    assert len(ids) == len(set(ids)) == 20

    spec = S.load(spec_path)
    run_study(spec, tmp_path / "uninterrupted", executor="serial", progress=False)
    assert _rows(out) == _rows(tmp_path / "uninterrupted")
