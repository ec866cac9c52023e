"""One way through the readers (issue #30, item 2): ``optcal.calibrate`` reads everything ``optcal calibrate``
reads, through the same function, and gives the same calibration: positions as CSV and as MATLAB v5 and v7.3
files; raw recordings as a text table, MATLAB v5 and v7.3 files, a ROS 1 bag and a ROS 2 bag (SQLite). The
files are written here from one simulated hand-held recording (`optcal simulate --raw`'s) and one simulated
positions set."""

from __future__ import annotations

import json

import numpy as np
import pytest
import robot_logs_files as R
from conftest import run_cli
from test_readers_wild import write_mat73

import optcal
from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.gravity import G0
from optcal.core.synthetic_imu import handheld_imu


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    from scipy.io import savemat

    d = tmp_path_factory.mktemp("readers")
    sim = handheld_imu(np.random.default_rng(1), n_poses=24, p_reseat_still=0.0)
    t, A, Wd = sim.acc.t, sim.acc.N, sim.gyro.N
    out = {}
    # raw recordings, in g (text, MAT) and in m/s² (the bags, whose messages define it)
    table = np.column_stack([t, A, Wd])
    out["raw text"] = d / "rec.csv"
    np.savetxt(out["raw text"], table, delimiter=",", header="t,ax,ay,az,gx,gy,gz", comments="")
    out["raw MAT v5"] = d / "rec.mat"
    savemat(out["raw MAT v5"], {"t": t, "ax": A[:, 0], "ay": A[:, 1], "az": A[:, 2]})
    out["raw MAT v7.3"] = write_mat73(d / "rec73.mat", {"t": t[:, None], "ax": A[:, :1], "ay": A[:, 1:2],
                                                         "az": A[:, 2:]})  # column vectors, as MATLAB saves them
    t_ns = R.EPOCH_NS + np.round(t * 1e9).astype(np.int64)
    for storage in ("ros1", "sqlite3"):
        out[f"raw ROS bag ({storage})"] = R.imu_bag(d / f"bag_{storage}", storage, t_ns, A * G0, np.radians(Wd))
    # positions: the means of a simulated 24-position set
    assert main(["simulate", "-o", str(d / "pos.csv"), "--seed", "3"]) == 0
    out["positions CSV"] = d / "pos.csv"
    N = np.loadtxt(d / "pos.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3))  # position, ax, ay, az
    out["positions MAT v5"] = d / "pos.mat"
    savemat(out["positions MAT v5"], {"ax": N[:, 0], "ay": N[:, 1], "az": N[:, 2]})
    out["positions MAT v7.3"] = write_mat73(d / "pos73.mat", {"P": N})
    return out


RAW = {"raw text": "g", "raw MAT v5": "g", "raw MAT v7.3": "g", "raw ROS bag (ros1)": None,
       "raw ROS bag (sqlite3)": None}
POSITIONS = ("positions CSV", "positions MAT v5", "positions MAT v7.3")


@pytest.mark.parametrize("kind", [*RAW, *POSITIONS])
def test_the_api_reads_what_the_command_reads(files, kind, capsys):
    """The same model and parameters to 1e-12 from ``optcal.calibrate`` and ``optcal calibrate --json``."""
    path = files[kind]
    raw = kind in RAW
    units = RAW.get(kind) if raw else "g"
    argv = ["calibrate", path, "--model", "linear9", "--json"] + (["--raw"] if raw else [])
    argv += ["--units", units] if units else []
    code, out, err = run_cli(argv, capsys)
    assert code == 0, err
    cli = json.loads(out)
    kw = {"units": units} if units else {}
    api = optcal.calibrate(path, "linear9", raw=raw, **kw)
    assert cli["n_positions"] == len(api.problem.data) >= 20
    np.testing.assert_allclose([cli["parameters"][n] for n in api.model.names], api.x, rtol=1e-12, atol=1e-15)


def test_the_same_refusal_for_a_raw_recording_given_as_positions(files, capsys):
    """One function decides, so the command and the API name a raw recording given as positions alike (with
    the option's name and the parameter's)."""
    code, out, err = run_cli(["calibrate", files["raw text"]], capsys)
    assert code == 2 and "looks like a raw recording, not a positions file" in err and err.strip().endswith(
        "pass --raw")
    with pytest.raises(InputError) as exc:
        optcal.calibrate(files["raw text"])
    assert str(exc.value) == err.strip().removeprefix("optcal calibrate: error: ").replace("--raw", "`raw`")
