"""The README's headline table, generated from the headline study's summary.json (never edited by hand).

    .venv/bin/python docs/scripts/headline_table.py [--summary out/compare/summary.json] [--readme README.md]
    .venv/bin/python docs/scripts/headline_table.py --check     # exit 1 when the README's table was edited

One row per solver configuration, one column per (model, scheme) cell: RMSE/CRLB (the RMS over the parameters
of each one's RMSE over the runs divided by its Cramér-Rao bound), then the same against the bound of the data
and the presets together, then the share of runs that reached the noise floor; then the median over the cells
of the median solver time (s) and of the evaluations per second. Rows in the order of the mean over the cells
of the second number (the study's ranking). The table goes between the README's two markers, the first of
which records the study (name, spec hash, trials) and the SHA-256 of the table, so that ``--check`` (and
tests/test_readme.py) can tell a table edited by hand from the generated one.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
START = re.compile(r"<!-- headline table: (?P<meta>.*?) sha256 (?P<sha>[0-9a-f]{64}) -->\n")
END = "<!-- end of the headline table -->"


def _cells(records: list[dict]) -> list[tuple[str, str]]:
    models = sorted({r["model"] for r in records}, key=lambda m: (m != "nonlinear12", m))
    schemes = sorted({r["scheme"] for r in records}, key=lambda s: (len(s), s))
    return [(m, s) for m in models for s in schemes if any(r["model"] == m and r["scheme"] == s for r in records)]


def _median(values: list[float]) -> float:
    v = sorted(values)
    k = len(v)
    return v[k // 2] if k % 2 else (v[k // 2 - 1] + v[k // 2]) / 2


def table(summary: dict) -> str:
    """The markdown table of a summary.json document (format 2)."""
    records = summary["records"]
    cells = _cells(records)
    by = {(r["solver"], r["model"], r["scheme"]): r for r in records}
    solvers = sorted({r["solver"] for r in records})

    def rank(s):
        vals = [by[(s, m, c)]["accuracy_presets"] for m, c in cells if (s, m, c) in by]
        vals = [v for v in vals if v is not None]
        return (sum(vals) / len(vals) if vals else float("inf"), s)

    head = "| solver | " + " | ".join(f"{m}, {c}" for m, c in cells) + " | runtime s | evaluations/s |"
    lines = [head, "|---" * (len(cells) + 3) + "|"]
    for s in sorted(solvers, key=rank):
        row = [f"`{s}`"]
        rt, ev = [], []
        for m, c in cells:
            r = by.get((s, m, c))
            if r is None:
                row.append("")
                continue
            acc = "–" if r["accuracy"] is None else f"{r['accuracy']:.2f}"
            pre = "–" if r["accuracy_presets"] is None else f"{r['accuracy_presets']:.2f}"
            row.append(f"{acc} / {pre} ({100 * r['success_rate']:.0f} %)")
            rt.append(r["runtime_median_s"])
            ev.append(r["evals_per_s"])
        row += [f"{_median(rt):.3g}", f"{_median(ev):,.0f}"]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def block(summary: dict) -> str:
    """The table with its two markers."""
    t = table(summary)
    st = summary["study"]
    meta = f"study {st['name']}, spec {st['spec_hash']}, {st['trials']:,} trials, {st['runs']} runs;"
    return f"<!-- headline table: {meta} sha256 {hashlib.sha256(t.encode()).hexdigest()} -->\n{t}{END}"


def readme_table(text: str) -> tuple[re.Match, str] | None:
    """The README's marker and table, or None without markers."""
    m = START.search(text)
    if not m or END not in text[m.end():]:
        return None
    return m, text[m.end():text.index(END, m.end())]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--summary", default=str(ROOT / "out" / "compare" / "summary.json"))
    ap.add_argument("--readme", default=str(ROOT / "README.md"))
    ap.add_argument("--check", action="store_true", help="only check that the README's table is the generated one")
    ns = ap.parse_args(argv)
    readme = Path(ns.readme)
    text = readme.read_text()
    found = readme_table(text)
    if found is None:
        print(f"{readme}: no headline table markers", file=sys.stderr)
        return 1
    m, current = found
    if ns.check:
        ok = hashlib.sha256(current.encode()).hexdigest() == m["sha"]
        print("the headline table is the generated one" if ok else "the headline table was edited by hand")
        return 0 if ok else 1
    summary = json.loads(Path(ns.summary).read_text())
    new = text[:m.start()] + block(summary) + text[text.index(END, m.end()) + len(END):]
    tmp = readme.with_name(readme.name + ".tmp")
    tmp.write_text(new)
    tmp.replace(readme)
    print(f"wrote the headline table of {summary['study']['name']} ({len(summary['records'])} records) into {readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
