"""The same outputs as before (issue #30): a change of the code's plan (the layers' move) changes nothing a user
sees. The corpus's calibrations and IMU fits (tests/test_corpus_wild.py) and a study's trials
(tests/test_study_api.py) are checked against tests/golden/outputs.json where they are computed; here, what those
do not cover: simulated positions through calibrate (with its figure's pixels), simulate --raw, discover, plan,
noise and a raw recording's figure, each command's written file compared value by value (tests/golden.py)."""

from __future__ import annotations

import json

import pytest
from golden import check as golden
from golden import pixels

from optcal.app.cli import main


def _run(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.out


@pytest.fixture(scope="module")
def positions(tmp_path_factory):
    work = tmp_path_factory.mktemp("same")
    pos = work / "pos.csv"
    assert main(["simulate", "--scheme", "36", "--seed", "7", "--noise-ug", "20", "--temp", "20:35",
                 "--effect", "cubic:K3_x=3e-4", "-o", str(pos), "-q"]) == 0
    return pos


def test_simulate_and_calibrate(positions, tmp_path, capsys):
    golden("simulate:36:seed7", positions.read_text())
    cal, fig = tmp_path / "cal.json", tmp_path / "fit.png"
    _run(["calibrate", positions, "--model", "nonlinear12", "-o", cal, "--plot", fig, "-q"], capsys)
    c = json.loads(cal.read_text())
    golden("calibrate:simulated", {"model": c["model"], "parameters": c["parameters"]})
    golden("calibrate:simulated:figure", pixels(fig))


def test_discover(positions, capsys):
    found = json.loads(_run(["discover", positions, "--json", "-q"], capsys))
    golden("discover:simulated", {k: found[k] for k in sorted(found) if k not in ("runtime_s", "elapsed_s")})


def test_plan(tmp_path, capsys):
    scheme = tmp_path / "plan.csv"
    _run(["plan", "--n", "12", "--seed", "3", "-o", scheme, "-q"], capsys)
    golden("plan:12:seed3", scheme.read_text())


def test_simulate_raw_then_imu(tmp_path, capsys):
    raw = tmp_path / "raw.csv"
    _run(["simulate", "--raw", "--seed", "5", "-o", raw, "-q"], capsys)
    golden("simulate:raw:seed5:sha", __import__("hashlib").sha256(raw.read_bytes()).hexdigest())
    out, fig = tmp_path / "imu.json", tmp_path / "raw.png"
    _run(["calibrate", raw, "--raw", "-o", out, "--plot", fig, "-q"], capsys)
    c = json.loads(out.read_text())
    golden("calibrate:raw:simulated", {"model": c["model"], "parameters": c["parameters"]})
    golden("calibrate:raw:simulated:figure", pixels(fig))
