"""docs/design.md against the code: the term table and the named models list every parameter in the
code's order, the positions CSV section names every column ``optcal.core.data`` reads, the calibration-file
section names every field ``optcal.core.calfile`` writes, and no file of the repository points outside it (the
conventions live in the repository) but for one path: the real corpus's default folder, which the corpus
locator (tests/corpus.py) and the Markdown pages that say where the corpus lives may name (issue #28)."""

import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from corpus import DEFAULT as CORPUS_DEFAULT

from optcal.core import calfile, calfile_schema, data
from optcal.core.data import PositionsData
from optcal.core.model import NAMED_MODELS, TERMS, get_model

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "design.md").read_text()


def section(number: str) -> str:
    """The text of section ``number`` ("3.1", "9") up to the next heading of the same or a higher level."""
    level = "##" if "." not in number else "###"
    m = re.search(rf"^{level} {re.escape(number)}\.? .*$", DOC, re.M)
    assert m, f"docs/design.md has no section {number}"
    rest = DOC[m.end():]
    stop = re.search(r"^##{0,1} " if level == "##" else r"^###? ", rest, re.M)
    return rest[: stop.start()] if stop else rest


def table_row(text: str, key: str) -> list[str]:
    """The cells of the table row whose first cell is `key` (in backticks)."""
    rows = [ln for ln in text.splitlines() if ln.startswith(f"| `{key}` |")]
    assert len(rows) == 1, f"expected one table row for {key!r}, found {len(rows)}"
    return [c.strip() for c in rows[0].strip().strip("|").split("|")]


def ticked(cell: str) -> list[str]:
    return re.findall(r"`([^`]+)`", cell)


@pytest.mark.parametrize("term", list(TERMS))
def test_term_table_lists_each_terms_parameters_in_order(term):
    cells = table_row(section("3.1"), term)
    assert ticked(cells[2]) == list(TERMS[term].params)
    assert cells[1] == TERMS[term].group


@pytest.mark.parametrize("name", list(NAMED_MODELS))
def test_named_models_list_their_parameters_in_vector_order(name):
    cells = table_row(section("3.3"), name)
    assert ticked(cells[2]) == list(get_model(name).names)


def test_term_table_is_in_the_codes_term_order():
    """Parameter vectors are ordered term by term in this order (design.md, "Named models and parameter order"), so
    the table must follow it."""
    order = [ticked(ln.split("|")[1])[0] for ln in section("3.1").splitlines()
             if ln.startswith("| `") and ticked(ln.split("|")[1])[0] in TERMS]
    assert order == list(TERMS)


def test_positions_csv_columns_are_documented():
    text = section("9.1")
    documented = set(ticked(text))
    missing = [c for c in data.REQUIRED + data.OPTIONAL if c not in documented]
    assert not missing, f"positions CSV columns missing from docs/design.md, 'Positions CSV': {missing}"
    for c in data.REQUIRED:  # the required columns are marked so
        assert any(ln.startswith("|") and f"`{c}`" in ln and "| yes |" in ln for ln in text.splitlines()), c


def _keys(d: dict, skip: tuple = ("parameters", "stderr")) -> set[str]:
    """Every key of the calibration file, nested ones included (not the parameter names)."""
    out = set()
    for k, v in d.items():
        out.add(k)
        if isinstance(v, dict) and k not in skip:
            out |= _keys(v, skip)
    return out


def test_calibration_file_fields_are_documented():
    """The fields come from what ``calibration_to_dict`` writes, for a model with a temperature and a
    drift term so that the optional ``context`` is written too."""
    model = get_model("linear9+temperature_bias+bias_drift")
    n = 12
    positions = PositionsData(N=np.ones((n, 3)), t=np.arange(n, dtype=float), temp=np.linspace(20, 30, n))
    obs = SimpleNamespace(to_dict=lambda: {"rank": model.n_params, "n_parameters": model.n_params,
                                           "unobservable": []})
    cal = SimpleNamespace(model=model, x=np.ones(model.n_params), stderr=np.full(model.n_params, np.nan),
                          problem=SimpleNamespace(data=positions, g_local=1.0), fit=SimpleNamespace(rms_g=1e-6),
                          solver="scipy-lm", observability=obs)
    written = calfile.calibration_to_dict(cal, source="positions.csv")
    keys = _keys(written)
    assert {"format", "format_version", "context", "T0", "t0"} <= keys
    text = section("9.3")
    documented = set(ticked(text))
    missing = sorted(keys - documented)
    assert not missing, f"calibration-file fields missing from docs/design.md, 'Calibration file': {missing}"
    assert set(calfile_schema.REQUIRED_FIELDS) <= documented
    assert f"format version {calfile.FORMAT_VERSION}" in text and f"`\"{calfile.FORMAT}\"`" in text


# -- nothing points outside the repository --------------------------------------------------------------
# The patterns are assembled here so that this file does not contain them itself.
OUTSIDE = ["../" + "shared", "/work/" + "shared", "shared/" + "data", "shared/" + "docs", "DESIGN" + ".md",
           "DESIGN" + " §", "ALGORITHMS" + ".md", "shared " + "DESIGN"]
# The one path outside allowed: the real corpus's default folder, in its locator and in the pages that say where
# the corpus lives (README, CONTRIBUTING, docs/*.md); everywhere else it is an offence like the others.
CORPUS_LOCATOR = Path("tests") / "corpus.py"
SKIP_DIRS = {".git", ".venv", "__pycache__", ".hypothesis", ".pytest_cache", ".ruff_cache", ".benchmarks", "build",
             "out", ".asv"}  # .asv: asv's environments and results (git-ignored)


def _repository_files():
    for path in sorted(ROOT.rglob("*")):
        rel = path.relative_to(ROOT)
        if any(p in SKIP_DIRS or p.endswith(".egg-info") for p in rel.parts[:-1]) or not path.is_file():
            continue
        yield rel, path


def _offences(rel: Path, text: str) -> list[str]:
    corpus_allowed = rel == CORPUS_LOCATOR or rel.suffix == ".md"
    offenders = []
    for i, line in enumerate(text.splitlines(), 1):
        if corpus_allowed:
            line = line.replace(CORPUS_DEFAULT, "")
        offenders += [f"{rel}:{i}: {pattern!r}" for pattern in OUTSIDE if pattern in line]
    return offenders


def test_no_file_points_outside_the_repository():
    offenders = []
    for rel, path in _repository_files():
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue  # figures and other binary files
        offenders += _offences(rel, text)
    assert not offenders, "references outside the repository:\n" + "\n".join(offenders)


def test_only_the_corpus_path_is_allowed_and_only_where_it_is_said():
    """The corpus's default folder passes in the locator and in a page; in code, or with anything else outside
    (another shared folder, an absolute path), it is still an offence."""
    line = f"the corpus: `{CORPUS_DEFAULT}/imucal/README.md`"
    assert _offences(Path("docs/real_data.md"), line) == []
    assert _offences(CORPUS_LOCATOR, f"DEFAULT = {CORPUS_DEFAULT!r}") == []
    assert _offences(Path("tests/test_x.py"), line) and _offences(Path("docs/scripts/x.py"), line)
    other = CORPUS_DEFAULT.replace("real", "other")
    assert _offences(Path("README.md"), f"see {other}") and _offences(Path("README.md"), "/work/" + "shared/x")


def test_design_doc_sections_cited_in_the_code_exist():
    """Every "docs/design.md §N" (and algorithms.md §N) cited anywhere names a section that exists."""
    algorithms = (ROOT / "docs" / "algorithms.md").read_text()
    headings = {
        "design.md": set(re.findall(r"^#{2,3} (\d+(?:\.\d+)?)\.? ", DOC, re.M)),
        "algorithms.md": set(re.findall(r"^## (\d+)\. ", algorithms, re.M)),
    }
    bad = []
    for rel, path in _repository_files():
        if path.suffix not in (".py", ".md", ".toml"):
            continue
        for doc, number in re.findall(r"(design\.md|algorithms\.md)\)?`{0,2} §(\d+(?:\.\d+)?)", path.read_text()):
            if number not in headings[doc]:
                bad.append(f"{rel}: {doc} §{number}")
    assert not bad, "citations of sections that do not exist:\n" + "\n".join(bad)
