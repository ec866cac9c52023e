"""The result store: one SQLite file in the study's output folder (``study.sqlite``).

Only the coordinating process writes. Each trial's row is inserted in its own transaction the moment
the trial finishes, so a study killed at any point (even ``kill -9``) keeps every finished trial and
loses at most the ones in flight; running the same spec into the folder again skips what is stored.
The folder remembers the hash of the canonical spec and refuses a different one.
"""

from __future__ import annotations

import csv
import json
import sqlite3
import time
from pathlib import Path

from optcal.core.atomicfile import atomic_write
from optcal.core.errors import InputError

FILE = "study.sqlite"

# (column, SQL type); JSON columns hold lists or dicts as text.
SCALAR = [
    ("trial_id", "TEXT PRIMARY KEY"), ("model", "TEXT"), ("scheme", "TEXT"), ("solver", "TEXT"),
    ("solver_name", "TEXT"), ("run", "INTEGER"), ("reference", "INTEGER"), ("reference_error_arcsec", "REAL"),
    ("status", "TEXT"), ("message", "TEXT"), ("success", "INTEGER"), ("converged", "INTEGER"), ("fun", "REAL"),
    ("chi2", "REAL"), ("dof", "INTEGER"), ("nfev", "INTEGER"), ("nit", "INTEGER"), ("runtime_s", "REAL"),
    ("wall_s", "REAL"), ("accuracy", "REAL"), ("ver_mean_ug", "REAL"), ("ver_sd_ug", "REAL"),
    ("ver_truth_mean_ug", "REAL"), ("nav_max_nmi", "REAL"), ("nav_mean_nmi", "REAL"), ("f_opt", "REAL"),
    # the evaluation budget, the final-target cost (trial.FINAL_GAP) and whether reaching it stopped the trial
    ("max_evals", "INTEGER"), ("target_f", "REAL"), ("at_target", "INTEGER"),
    # why the solve ended (optcal.solvers.base.STOP_REASONS: budget, target, own, stagnation, ...); nfev: evaluations
    # used
    ("stop_reason", "TEXT"),
]
# anytime: [evaluations, best cost, accuracy] on the trace's grid (optcal.studies.trial.anytime_on_grid); anytime_s: the
# solver time (s) at each of its points (optcal.studies.scoring.seconds_on_grid)
JSON = ["names", "x_true", "x_est", "err", "err_proj", "crlb", "observable", "null_dirs", "null_err", "ver_err",
        "ver_truth", "trace", "nav_curve", "crlb_presets", "anytime", "anytime_s"]
COLUMNS = [c for c, _ in SCALAR] + JSON
# the only columns that may differ between identical runs (anytime_s: the solver time at each anytime point)
TIMING = ("runtime_s", "wall_s", "anytime_s")


class Store:
    """A study folder's SQLite store."""

    def __init__(self, folder: str | Path, spec_hash: str, spec_json: str):
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.path = self.folder / FILE
        self.conn = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        # WAL: a reader (a report while the study runs) never blocks the writer; NORMAL sync is safe
        # against a killed process (only a power cut can lose the last transactions).
        self.conn.execute("PRAGMA journal_mode=WAL")
        self.conn.execute("PRAGMA synchronous=NORMAL")
        cols = ", ".join(f"{c} {t}" for c, t in SCALAR) + ", " + ", ".join(f"{c} TEXT" for c in JSON)
        self.conn.execute("BEGIN IMMEDIATE")
        self.conn.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT)")
        self.conn.execute(f"CREATE TABLE IF NOT EXISTS trials ({cols})")
        # A store written by an older optcal lacks the newer columns (crlb_presets, f_opt, anytime): add
        # them, empty (NULL in the old rows).
        have = {r[1] for r in self.conn.execute("PRAGMA table_info(trials)")}
        for c, typ in SCALAR[1:] + [(c, "TEXT") for c in JSON]:
            if c not in have:
                self.conn.execute(f"ALTER TABLE trials ADD COLUMN {c} {typ}")
        old = self.meta("spec_hash")
        if old is None:
            self.conn.executemany("INSERT INTO meta VALUES (?, ?)", [
                ("spec_hash", spec_hash), ("spec", spec_json), ("created", time.strftime("%Y-%m-%d %H:%M:%S")),
                ("wall_s", "0"), ("sessions", "[]")])
            self.conn.execute("COMMIT")
        else:
            self.conn.execute("COMMIT")
            if old != spec_hash:
                self.close()
                raise InputError(
                    f"folder {self.folder} holds a study of a different spec (hash {old}, this spec {spec_hash}); "
                    "run it into another --out folder, or delete the folder to start again")

    @classmethod
    def open_existing(cls, folder: str | Path) -> Store:
        path = Path(folder) / FILE
        if not path.is_file():
            raise InputError(f"{folder} holds no study ({FILE} not found); run `optcal study run SPEC --out {folder}`")
        conn = sqlite3.connect(path, timeout=30.0)
        try:
            row = conn.execute("SELECT value FROM meta WHERE key = 'spec_hash'").fetchone()
            spec = conn.execute("SELECT value FROM meta WHERE key = 'spec'").fetchone()
        except sqlite3.DatabaseError as exc:
            raise InputError(f"{path} is not a study store ({exc})") from None
        finally:
            conn.close()
        if row is None:
            raise InputError(f"{path} is not a study store (no spec recorded)")
        return cls(folder, row[0], spec[0])

    def close(self) -> None:
        self.conn.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- meta ----------------------------------------------------------------------------------
    def meta(self, key: str):
        r = self.conn.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return None if r is None else r[0]

    def set_meta(self, key: str, value: str) -> None:
        self.conn.execute("BEGIN IMMEDIATE")
        self.conn.execute("INSERT OR REPLACE INTO meta VALUES (?, ?)", (key, value))
        self.conn.execute("COMMIT")

    @property
    def spec(self) -> dict:
        return json.loads(self.meta("spec"))

    def add_session(self, info: dict) -> None:
        """Record one `study run` session (executor, workers, trials run, wall time)."""
        sessions = json.loads(self.meta("sessions") or "[]")
        sessions.append(info)
        self.set_meta("sessions", json.dumps(sessions))
        self.set_meta("wall_s", repr(float(self.meta("wall_s") or 0) + info.get("wall_s", 0.0)))

    # -- trials --------------------------------------------------------------------------------
    def finished(self) -> set[str]:
        return {r[0] for r in self.conn.execute("SELECT trial_id FROM trials")}

    def write(self, row: dict) -> None:
        """Insert one trial's row in its own transaction."""
        values = [row.get(c) for c, _ in SCALAR] + [
            None if row.get(c) is None else json.dumps(row[c]) for c in JSON]
        unknown = set(row) - set(COLUMNS)
        if unknown:
            raise ValueError(f"unknown column(s) {sorted(unknown)}")
        self.conn.execute("BEGIN IMMEDIATE")
        try:
            self.conn.execute(f"INSERT INTO trials ({', '.join(COLUMNS)}) VALUES ({', '.join('?' * len(COLUMNS))})",
                              values)
        except BaseException:
            self.conn.execute("ROLLBACK")
            raise
        self.conn.execute("COMMIT")

    def rows(self) -> list[dict]:
        """Every stored trial as a dict (JSON columns decoded), in trial-id order."""
        cur = self.conn.execute(f"SELECT {', '.join(COLUMNS)} FROM trials ORDER BY trial_id")
        out = []
        for r in cur:
            d = dict(zip(COLUMNS, r))
            for c in JSON:
                d[c] = None if d[c] is None else json.loads(d[c])
            out.append(d)
        return out

    def count(self) -> tuple[int, int]:
        n, f = self.conn.execute("SELECT COUNT(*), COALESCE(SUM(status = 'failed'), 0) FROM trials").fetchone()
        return int(n), int(f)

    # -- export --------------------------------------------------------------------------------
    def export(self, folder: str | Path | None = None) -> list[Path]:
        """Write ``trials.csv`` (and ``trials.parquet`` when pyarrow is installed); return the paths."""
        folder = Path(folder or self.folder)
        cur = self.conn.execute(f"SELECT {', '.join(COLUMNS)} FROM trials ORDER BY trial_id")
        rows = cur.fetchall()
        paths = [folder / "trials.csv"]
        # each through a temporary file beside it, renamed when complete (optcal.core.atomicfile)
        with atomic_write(paths[0], overwrite=True, newline="") as fh:
            w = csv.writer(fh)
            w.writerow(COLUMNS)
            w.writerows(rows)
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            return paths
        table = pa.table({c: [r[i] for r in rows] for i, c in enumerate(COLUMNS)})
        with atomic_write(folder / "trials.parquet", overwrite=True, binary=True) as fh:
            pq.write_table(table, fh)
        paths.append(folder / "trials.parquet")
        return paths
