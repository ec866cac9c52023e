"""A file per pose (three labs of issue #29's trials: a phone's six files, an AVR lab's six faces, a rocket club's
six logs, each concatenated by hand): ``optcal calibrate A B C … --raw`` joins them in turn (each file's clock may
restart at 0), a missing sample between two, so that no rest spans two files."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import run_cli

from optcal.app.cli import main
from optcal.core.errors import InputError
from optcal.core.recording import read_recording
from optcal.core.recording.join import join_recordings
from optcal.core.schemes import scheme
from optcal.core.synthetic_recording import poses_recording


def _pose_files(tmp_path, n=12):
    """One file per pose: 0.5 s of handling (a quarter turn into the pose), 3 s held, its clock from 0."""
    dirs = scheme(f"random:{n}", np.random.default_rng(0))
    paths = []
    for k, d in enumerate(dirs):
        start = np.roll(d, 1)  # the pose the hand brings it from
        syn = poses_recording(np.random.default_rng(k), np.vstack([start, d]), hold_s=[0.3, 3.0],
                              turn_rate_dps=180.0, noise_g=1e-3)
        rec = syn.recording
        path = tmp_path / f"pose{k:02d}.csv"
        np.savetxt(path, np.column_stack([rec.t - rec.t[0], rec.N]), delimiter=",", header="t,ax,ay,az",
                   comments="", fmt="%.6f")
        paths.append(path)
    return paths


def test_a_file_per_pose_is_one_recording_and_no_rest_spans_two(tmp_path, capsys):
    paths = _pose_files(tmp_path)
    recs = [read_recording(p, units="g") for p in paths]
    joined = join_recordings(recs)
    assert len(joined) == sum(len(r) for r in recs) + len(recs) - 1
    assert np.all(np.diff(joined.t) > 0) and np.isnan(joined.N).any(axis=1).sum() == len(recs) - 1
    assert main(["calibrate", *map(str, paths), "--raw", "--units", "g", "--model", "linear9", "--json"]) == 0
    import json

    out = json.loads(capsys.readouterr().out)
    iv = np.asarray(out["recording"]["intervals"])
    ends = np.cumsum([len(r) + 1 for r in recs])  # each file's end (its join sample) in the joined samples
    which = np.searchsorted(ends, iv[:, 0], side="right")
    assert np.all(iv[:, 1] <= ends[which] - 1)  # every rest ends inside the file it starts in
    assert sorted(set(which.tolist())) == list(range(len(recs)))  # every file's pose found
    assert main(["calibrate", *map(str, paths), "--raw", "--units", "g", "--model", "linear9"]) == 0
    assert f"{len(recs)} files joined in turn" in capsys.readouterr().out


def test_files_that_do_not_go_together_are_refused(tmp_path, capsys):
    paths = _pose_files(tmp_path, 3)
    a = np.loadtxt(paths[1], delimiter=",", skiprows=1)
    a[:, 0] *= 2.0  # half the rate
    np.savetxt(paths[1], a, delimiter=",", header="t,ax,ay,az", comments="", fmt="%.6f")
    assert main(["calibrate", *map(str, paths), "--raw", "--units", "g"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Hz: give recordings of one sensor at one rate" in err
    assert main(["calibrate", str(paths[0]), str(paths[2])]) == 2
    assert "2 files are read as one raw recording: give --raw" in capsys.readouterr().err
    other = replace(read_recording(paths[2], units="g"), units="m/s2")
    with pytest.raises(InputError, match="give recordings of one sensor in one unit"):
        join_recordings([read_recording(paths[0], units="g"), other])


def test_imu_joins_files_each_with_its_gyroscope(tmp_path, capsys):
    """``optcal imu A B C``: an IMU recording split into three files at mid-rest, each file's clock from 0, is
    read as one: its accelerometer and gyroscope joined in turn (a missing sample between two files), its rests
    found as in the whole file (the two split rests found in each part), no motion fitted across a join, and the
    gyroscope's parameters those of the whole file within their standard errors."""
    import json

    from optcal.core.gyro import draw_truth, get_gyro_model, simulate_imu

    rng = np.random.default_rng(0)
    model = get_gyro_model(False)
    x = draw_truth(model, rng, 1000.0)
    x[9:12] += 32768 / 1000.0
    d = simulate_imu(model, x, poses=24, rest_s=3.0, rng=rng).data
    table = np.column_stack([d.t, d.F, np.round(d.W)])
    head = "t,ax,ay,az,gx,gy,gz"
    whole = tmp_path / "whole.csv"
    np.savetxt(whole, table, delimiter=",", header=head, comments="", fmt="%.9g")
    cuts = [(d.rests[k, 0] + d.rests[k, 1]) // 2 for k in (8, 16)]  # the middle of rests 8 and 16
    parts = []
    for k, (a, b) in enumerate(zip([0, *cuts], [*cuts, len(table)])):
        part = table[a:b].copy()
        part[:, 0] -= part[0, 0]
        path = tmp_path / f"part{k}.csv"
        np.savetxt(path, part, delimiter=",", header=head, comments="", fmt="%.9g")
        parts.append(str(path))
    args = ["--gyro-units", "counts", "--gyro-scale", "1000", "--model", "linear9", "--json"]
    code, text, err = run_cli(["imu", str(whole), *args], capsys)
    assert code == 0, err
    one = json.loads(text)
    code, text, err = run_cli(["imu", *parts, *args], capsys)
    assert code == 0, err
    joined = json.loads(text)
    assert len(joined["recording"]["intervals"]) == len(one["recording"]["intervals"]) + 2
    # calibrate on the same files, judging the rests on each file's gyroscope, takes imu's rests
    code, text, err = run_cli(["calibrate", *parts, "--raw", "--gyro-columns", "gx,gy,gz", "--model", "linear9",
                               "--json"], capsys)
    assert code == 0, err
    assert json.loads(text)["recording"]["intervals"] == joined["recording"]["intervals"]
    g1, g3 = one["gyroscope"], joined["gyroscope"]
    assert g3["data"]["n_motions"] == g1["data"]["n_motions"]  # the motions of each part; none across a join
    for k in ("K_x", "K_y", "K_z", "T_xy", "T_yz"):
        assert abs(g3["parameters"][k] - g1["parameters"][k]) < 3 * g1["stderr"][k], k
