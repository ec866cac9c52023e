"""The documentation site (mkdocs.yml): the strict build passes, its API reference renders the front door's
signatures as the functions have them, and the strict build does fail on a broken link or anchor."""

from __future__ import annotations

import ast
import html
import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mkdocs", reason="mkdocs is not installed: pip install -e '.[test]' installs the docs' tools")

ROOT = Path(__file__).resolve().parent.parent


def _build(config: Path, site: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config), "-d", str(site)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> str:
    site = tmp_path_factory.mktemp("site")
    out = _build(ROOT / "mkdocs.yml", site)
    assert out.returncode == 0, out.stderr[-3000:]
    return (site / "reference" / "index.html").read_text(encoding="utf-8")


def _split(params: str) -> list[str]:
    """The parameters of a rendered signature, split at the commas outside brackets."""
    items, depth, start = [], 0, 0
    for i, ch in enumerate(params):
        depth += ch in "([{"
        depth -= ch in ")]}"
        if ch == "," and depth == 0:
            items.append(params[start:i])
            start = i + 1
    items.append(params[start:])
    return [s.strip() for s in items if s.strip()]


def _rendered_signature(page: str, identifier: str) -> str:
    """The signature block under the heading of ``identifier``, as text."""
    at = page.index(f'id="{identifier}"')
    block = re.search(r'class="doc-signature[^"]*"[^>]*>(.*?)</pre>', page[at:], re.S)
    assert block is not None, f"no signature rendered for {identifier}"
    return re.sub(r"\s+", " ", html.unescape(re.sub(r"<[^>]+>", "", block[1]))).strip()


@pytest.mark.parametrize("name, returns", [("calibrate", "Calibration"), ("calibrate_imu", None)])
def test_reference_renders_the_signature(reference, name, returns):
    import optcal

    fn = getattr(optcal, name)
    where = f"{fn.__module__}.{name}"  # the reference's anchor: where the function is defined
    text = _rendered_signature(reference, where)
    m = re.fullmatch(rf"{name}\((.*)\)(?: -> (\S+))?", text)
    assert m is not None, text
    assert m[2] == returns
    rendered = _split(m[1])
    expected, star = [], False
    for p in inspect.signature(fn).parameters.values():
        star = star or p.kind is p.VAR_POSITIONAL
        if p.kind is p.KEYWORD_ONLY and not star:
            expected.append(("*", inspect.Parameter.empty))
            star = True
        prefix = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "")
        expected.append((prefix + p.name, p.default))
    got = []
    for item in rendered:
        head, _, default = item.partition("=")
        value = ast.literal_eval(default.strip()) if default else inspect.Parameter.empty
        got.append((head.split(":")[0].strip(), value))
    assert got == expected
    # the heading names the function as users import it
    heading = re.search(rf'<h3 id="{re.escape(where)}"[^>]*>(.*?)</h3>', reference, re.S)
    assert re.sub(r"<[^>]+>|¶", "", html.unescape(heading[1])).split() == [f"optcal.{name}"]


def test_strict_build_fails_on_a_broken_link_and_anchor(tmp_path):
    """The validation of mkdocs.yml, inherited by a two-page site: a link to a missing page and one to a missing
    anchor are each a warning, which --strict turns into a failed build naming it."""
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "index.md").write_text("# Home\n\nSee [the other page](other.md#no-such-heading) and [gone](gone.md).\n")
    (docs / "other.md").write_text("# Other\n\n## A heading\n")
    config = tmp_path / "mkdocs.yml"
    config.write_text(f"INHERIT: {ROOT / 'mkdocs.yml'}\ndocs_dir: docs\nplugins: [search]\n"
                      "nav: [index.md, other.md]\n")
    out = _build(config, tmp_path / "site")
    assert out.returncode != 0
    assert "'gone.md'" in out.stderr
    assert "'#no-such-heading'" in out.stderr


def test_reference_covers_the_front_door(reference):
    """Every function users import from optcal's front door has its heading (docs/api.md lists them)."""
    # a heading's text is the name, then its labels (dataclass, property, ...)
    headings = {re.sub(r"<[^>]+>|¶", "", html.unescape(h)).split()[0]
                for h in re.findall(r"<h3 id=[^>]*>(.*?)</h3>", reference, re.S)}
    front_door = ["calibrate", "apply", "read_recording", "noise", "calibrate_imu", "apply_gyro", "study"]
    assert {f"optcal.{name}" for name in front_door} <= headings, sorted(headings)
    assert {"optcal.core.calibration.Calibration", "optcal.solvers.base.Solver",
            "optcal.solvers.base.SolverResult"} <= headings
