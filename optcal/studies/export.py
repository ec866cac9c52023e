"""``optcal study export DIR --format FORMAT -o OUT``: a study's results for other tools.

- ``ioh``: the runs in the IOHprofiler format, for IOHanalyzer and iohinspector (below);
- ``github-action-benchmark``: per solver its RMSE/CRLB, verification error and median run time
  (``smaller_is_better.json``) and its share at the noise floor and anytime ECDF areas
  (``bigger_is_better.json``), in the ``customSmallerIsBetter`` / ``customBiggerIsBetter`` JSON of
  github-action-benchmark, so that a hosted CI service charts them per commit and gates on them; each value
  carries its 95 % bootstrap interval over the runs as its range;
- ``junit``: the baseline check of :mod:`optcal.studies.baseline` (``--baseline FILE``; the committed
  optcal/studies/ci_tolerances.toml for the CI spec) as JUnit XML (``tolerances.xml``): a test case per solver and
  metric, failed when the baseline lies outside the study's interval on the bad side.

The format is the one IOHexperimenter's Analyzer logger writes (json + .dat): per algorithm a folder with,
per problem, a meta file ``IOHprofiler_f{fid}_{name}.json`` and a data file
``data_f{fid}_{name}/IOHprofiler_f{fid}_DIM{n}.dat``. The data file holds one block per run: a header line
``evaluations raw_y``, then a line ``evaluations best-so-far cost`` at each improvement, the first at
evaluation 1 (a reader starts a new run at each ``evaluations == 1``). The meta file lists the runs in the
same order, each with its instance, its evaluations and its best point.

The mapping:

- a problem (function) per model × scheme of the spec, ids 1, 2, ... in the spec's order, named
  ``{model}_{scheme}``, dimension = the model's number of parameters, minimised;
- an instance per Monte-Carlo run (instance = run + 1): run i's data set is the same for every solver;
- an algorithm per solver configuration (the spec's label); the folder name is the label with characters
  other than letters, digits and ``._+-`` replaced by ``-``;
- raw_y = the best cost so far (Σ e², the study's cost), at the study's 10-per-decade evaluation grid: an
  improvement is logged at the first grid point at or after it, so its evaluation count is an upper bound
  within a factor 1.26. A solver that evaluates a first population in one batch has its first recorded
  value (the batch's best) at evaluation 1.

Left out: turntable (reference) configurations, which minimise another cost on other data, and failed
trials, which have no curve.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
from pathlib import Path

from optcal.core.atomicfile import write_atomic
from optcal.core.errors import InputError
from optcal.studies.store import Store

FORMATS = ("ioh", "github-action-benchmark", "junit")
SUITE = "optcal"


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]", "-", name).strip(".") or "x"


def _curve(row: dict) -> list[tuple[int, float]]:
    """The best-so-far cost at each improvement, from the row's anytime record (or its trace in a store
    written before anytime records), the first point at evaluation 1."""
    pts = row.get("anytime") or row.get("trace") or []
    top = int(row.get("nfev") or 0) or None  # the grid's last point may lie past the last evaluation
    out: list[tuple[int, float]] = []
    for p in pts:
        e, y = int(p[0]) if top is None else min(int(p[0]), top), float(p[1])
        if not out:
            out.append((1, y))
        elif y < out[-1][1]:
            out.append((max(e, out[-1][0] + 1), y))
    return out


def _problems(spec: dict) -> dict[tuple[str, str], tuple[int, str]]:
    """(model, scheme) -> (function id, function name), in the spec's order."""
    out = {}
    for m in spec["models"]:
        for s in spec["schemes"]:
            out[m, s] = (len(out) + 1, f"{m}_{s}")
    return out


def write_ioh(rows: list[dict], spec: dict, spec_hash: str, folder: Path) -> dict:
    """Write the IOHprofiler files of ``rows`` into ``folder`` (which exists); return counts."""
    problems = _problems(spec)
    configs = {c["label"]: c for c in spec["solvers"]}
    rows = [r for r in rows if r["status"] == "ok" and not r.get("reference")]
    labels = [c["label"] for c in spec["solvers"] if not c.get("reference")]
    labels += sorted({r["solver"] for r in rows} - set(labels))
    dirs: dict[str, str] = {}
    for label in labels:
        d = _safe(label)
        while d in dirs.values():
            d += "_"
        dirs[label] = d
    n_runs = n_files = 0
    for label in labels:
        mine = [r for r in rows if r["solver"] == label]
        if not mine:
            continue
        cfg = configs.get(label, {})
        info = json.dumps({k: cfg[k] for k in ("name", "options", "budget") if k in cfg}, sort_keys=True)
        adir = folder / dirs[label]
        for (model, scheme), (fid, fname) in problems.items():
            runs = sorted((r for r in mine if r["model"] == model and r["scheme"] == scheme), key=lambda r: r["run"])
            runs = [(r, _curve(r)) for r in runs]
            runs = [(r, c) for r, c in runs if c]
            if not runs:
                continue
            dim = len(runs[0][0]["names"])
            safe = _safe(fname)
            dat_rel = f"data_f{fid}_{safe}/IOHprofiler_f{fid}_DIM{dim}.dat"
            (adir / dat_rel).parent.mkdir(parents=True, exist_ok=True)
            lines = []
            meta_runs = []
            for r, curve in runs:
                lines.append("evaluations raw_y")
                lines += [f"{e} {y:.17g}" for e, y in curve]
                meta_runs.append({"instance": int(r["run"]) + 1, "evals": int(r["nfev"]),
                                  "best": {"evals": curve[-1][0], "y": float(r["fun"]),
                                           "x": [float(v) for v in r["x_est"]]}})
                n_runs += 1
            write_atomic(adir / dat_rel, "\n".join(lines) + "\n", overwrite=True)
            meta = {
                "version": "0.3.18", "suite": SUITE, "function_id": fid, "function_name": fname,
                "maximization": False, "algorithm": {"name": label, "info": info},
                "experiment_attributes": [{"study": spec["name"]}, {"spec_hash": spec_hash},
                                          {"seed": str(spec["seed"])}, {"noise_ug": str(spec["noise_ug"])}],
                "attributes": ["evaluations", "raw_y"],
                "scenarios": [{"dimension": dim, "path": dat_rel, "runs": meta_runs}],
            }
            write_atomic(adir / f"IOHprofiler_f{fid}_{safe}.json", json.dumps(meta, indent=1), overwrite=True)
            n_files += 1
    return {"runs": n_runs, "algorithms": sum(1 for d in folder.iterdir() if d.is_dir()),
            "problems": len({k for k in problems}), "files": n_files}


def write_benchmark_action(rows: list[dict], spec: dict, folder: Path, commit: str | None) -> dict:
    """Write github-action-benchmark's two custom JSON files into ``folder``; return counts."""
    from optcal.studies.anytime import collect
    from optcal.studies.baseline import measure

    measured = measure(rows, spec["seed"])
    extra = f"study {spec['name']}, {spec['runs']} runs, seed {spec['seed']}" + (f", code {commit}" if commit else "")

    def entry(name, what, unit, v, lo=None, hi=None):
        e = {"name": f"{name}: {what}", "unit": unit, "value": v, "extra": extra}
        if lo is not None and math.isfinite(lo) and math.isfinite(hi):
            e["range"] = f"95 % CI [{lo:.4g}, {hi:.4g}]"
        return e

    small, big = [], []
    for name, m in measured.items():
        for key, what, unit in (("accuracy", "RMSE/CRLB", "RMSE/CRLB"), ("ver_mean_ug", "verification error", "µg"),
                                ("runtime_median_s", "median run time", "s")):
            if math.isfinite(m[key][0]):
                small.append(entry(name, what, unit, *m[key]))
        if math.isfinite(m["success_rate"][0]):
            big.append(entry(name, "share of runs at the noise floor", "fraction", *m["success_rate"]))
    for rec in collect(rows).table(spec["seed"]):
        for kind in ("cost", "accuracy"):
            v = rec[f"{kind}_area"]
            if math.isfinite(v):
                big.append(entry(rec["solver"], f"anytime ECDF area ({kind} targets)", "area", v,
                                 *rec[f"{kind}_area_ci"]))
    write_atomic(folder / "smaller_is_better.json", json.dumps(small, indent=1, allow_nan=False), overwrite=True)
    write_atomic(folder / "bigger_is_better.json", json.dumps(big, indent=1, allow_nan=False), overwrite=True)
    return {"runs": sum(r["status"] == "ok" for r in rows), "algorithms": len(measured),
            "problems": len({(r["model"], r["scheme"]) for r in rows}), "files": 2}


def write_junit(rows: list[dict], spec: dict, folder: Path, baseline: str | Path | None) -> dict:
    """Write the baseline check (:mod:`optcal.app.study_ci`) as JUnit XML into ``folder``; return counts."""
    from optcal.studies.baseline import TOLERANCES, check, junit_xml, load_baseline, measure, regressions

    if baseline is None:
        if spec["name"] not in ("ci", "ci-quick"):
            raise InputError(f"study {spec['name']}: give its `baseline` file (write one with "
                             "`python -m optcal.app.study_ci --spec SPEC --propose`)")
        baseline = TOLERANCES
    results = check(measure(rows, spec["seed"]), load_baseline(baseline))
    write_atomic(folder / "tolerances.xml", junit_xml(results, spec["name"]), overwrite=True)
    return {"runs": sum(r["status"] == "ok" for r in rows), "algorithms": len({r.solver for r in results}),
            "problems": len({(r["model"], r["scheme"]) for r in rows}), "files": 1,
            "regressions": regressions(results)}


def export(study: str | Path, out: str | Path, fmt: str = "ioh", baseline: str | Path | None = None) -> dict:
    """Export the study in ``study`` to the new folder ``out``; nothing is written there unless the whole
    export succeeds (it is written to a temporary folder beside ``out`` and renamed). ``baseline``: the
    baseline file of the ``junit`` format."""
    if fmt not in FORMATS:
        raise InputError(f"unknown export format {fmt!r}; use one of {', '.join(FORMATS)}")
    if baseline is not None and fmt != "junit":
        raise InputError("`baseline` is for the junit `format`")
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(f"{out} exists and is not an empty folder; export into a new one")
    with Store.open_existing(study) as st:
        spec, rows, spec_hash = st.spec, st.rows(), st.meta("spec_hash")
        sessions = json.loads(st.meta("sessions") or "[]")
    if not any(r["status"] == "ok" for r in rows):
        raise InputError(f"{study} holds no finished trial to export")
    parent = out.absolute().parent
    made = [p for p in [parent, *parent.parents] if not p.exists()]
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=parent))
    try:
        if fmt == "ioh":
            counts = write_ioh(rows, spec, spec_hash, tmp)
        elif fmt == "junit":
            counts = write_junit(rows, spec, tmp, baseline)
        else:
            commits = [x.get("code") for x in sessions if x.get("code")]
            counts = write_benchmark_action(rows, spec, tmp, commits[-1] if commits else None)
        if not counts["runs"]:
            raise InputError(f"{study} holds no finished in-field trial to export")
        os.chmod(tmp, 0o777 & ~_umask())
        if out.exists():
            out.rmdir()  # empty (checked above)
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        for p in made:  # innermost first
            try:
                p.rmdir()
            except OSError:
                break
        raise
    return {**counts, "folder": str(out)}


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m
