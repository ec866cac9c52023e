"""The tables of docs/noise.md, "The floor on hand-held logs": is the noise floor of a position
(optcal.core.recording.floor) larger than the scatter of the position means on poses turned and held by hand? Mikov,
Reginya & Moschevikin's five MPU-9150 recordings (the real corpus's mikov/, MIT; tests/corpus.py: ``OPTCAL_CORPUS``,
else the shared folder beside the clone), each read as tests/test_corpus_wild.py reads it.

    .venv/bin/python docs/scripts/floor_mikov.py [--seeds N]

It prints four markdown tables:

1. ``optcal calibrate FILE --raw --units m/s2 --gravity-ms2 9.81 --rate 100 --columns ax=0,ay=1,az=2 --json`` per
   recording: positions, model, residual RMS, the floor and σ/√n (RMS over positions of each residual's σ,
   input-referred), their ratio, χ²/dof and p, and the calibration against the source's table: the largest
   |difference| over the three axes, in optcal's standard errors, of the scale factors (row norms of the
   sensitivity matrix), the offsets and the cosines of the angles between the axes (tests/test_corpus_wild.py's
   gauge-free comparison).
2. The floor against the scatter it must predict: the same model fitted again without each position in turn
   (optcal.app.fit.calibrate on the command's intervals, no recheck), the left-out position's prediction error e_i
   scaled by √(1 − h_i) (h its leverage in the whole fit) so that its SD is the position's σ_i when the floor is
   right; "scatter" is the RMS of those, and each floor's ratio to it is 1/RMS(e_i√(1 − h_i)/σ_i). Floors: the
   command's, σ/√n, and σ/√n of the samples' component along the specific force (a turn of the pose does not
   enter it). The pooled row is over all 115 positions.
3. Where a larger floor would come from: the floor fitted on the still middle of each interval (its first and
   last fifth cut off) and on the longest rest alone (N and B fitted there, the floor of every interval from
   them); the turn check (the per-axis flicker level against the one read along the force, in standard errors,
   ``NoiseFloor.turn_z``); and the half-interval test: half the difference of the two halves' means of each
   interval, along the force and across it, RMS over intervals in units of σ/√n of that component.
4. Simulated recordings (optcal.core.synthetic_recording.poses_recording) with each recording's poses (the
   directions of its position means), hold times and gaps, and stationary white + flicker noise at its fitted
   levels (RMS over the axes of N and B): the floor against the actual scatter of the means about their average
   (the floor's definition), RMS over positions, axes and SEEDS recordings (default 100); also with B = 0.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from optcal.app.cli import main
from optcal.app.fit import calibrate
from optcal.core.analysis import position_sigma, white_sigma
from optcal.core.problem import CalibrationProblem
from optcal.core.recording import floor as F
from optcal.core.recording import given_intervals, positions_from_recording, read_recording
from optcal.core.synthetic_recording import OFFSET, SCALE, poses_recording

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder

DATA = corpus_root() / "mikov"
G0 = 9.80665
RATE = 100.0
G_LOCAL = 9.81 / G0  # the source's |g| = 9.81 m/s²
COLUMNS = "ax=0,ay=1,az=2"
ARGS = ["--raw", "--units", "m/s2", "--gravity-ms2", "9.81", "--rate", "100", "--columns", COLUMNS, "--json"]
# The source's table and its comparison with optcal's gauge: tests/test_corpus_wild.py's MIKOV (images/real_imu.png
# of github.com/mikoff/imu-calib; the folder's README)
from test_corpus_wild import _mikov_ref as source  # noqa: E402
from test_corpus_wild import _ours  # noqa: E402


def ours(p, se):
    """Scale factors, offsets (output units) and cosines from optcal's parameters (tests/test_corpus_wild.py's
    ``_ours``), with standard errors (the cosines' to first order: those of S_yz, S_zy, S_zx)."""
    scale, offset, cos = _ours(p)
    K = np.array([p["K_x"], p["K_y"], p["K_z"]])
    se_k = np.array([se["K_x"], se["K_y"], se["K_z"]])
    se_b = K * np.array([se["b_x"], se["b_y"], se["b_z"]])
    se_c = np.array([se.get("S_yz", np.nan), se.get("S_zy", np.nan), se.get("S_zx", np.nan)])
    return (scale, se_k), (offset, se_b), (cos, se_c)


def command(i):
    """The command's JSON for recording i."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(["calibrate", str(DATA / f"imu{i}.log.gz"), *ARGS])
    assert code == 0, f"imu{i}: exit {code}"
    return json.loads(out.getvalue())


def positions(i, intervals):
    rec = read_recording(DATA / f"imu{i}.log.gz", columns=COLUMNS, rate=RATE, units="m/s2")
    return rec, positions_from_recording(rec, given_intervals(rec, np.asarray(intervals)))


def along_sigma(rec, intervals, problem, x):
    """σ/√n of each interval's samples projected on its specific force's direction (output units over K), g."""
    A = problem.specific_force(x)
    u = A / np.linalg.norm(A, axis=1, keepdims=True)
    K = problem._K0
    return np.array([np.std((rec.N[s:e] / K) @ w, ddof=1) / np.sqrt(e - s) for (s, e), w in zip(intervals, u)])


def leave_one_out(data, model):
    """The fit, each position's prediction error from the others times √(1 − h), and the fit's problem."""
    cal = calibrate(data, model, g_local=G_LOCAL, recheck=False)
    full = CalibrationProblem(cal.model, data, g_local=G_LOCAL, check=False)
    err = np.empty(len(data))
    for j in range(len(data)):
        others = calibrate(data.subset(np.delete(np.arange(len(data)), j)), cal.model, g_local=G_LOCAL,
                           recheck=False, force_weak=True)
        err[j] = full.position_residuals(others.x)[j]
    return cal, err * np.sqrt(1.0 - cal.diagnostics.leverage)


def floor_with(N2, B2, rec, intervals, white):
    """The floor of ``intervals`` for white level N² and flicker level B² per axis (floor.py's model)."""
    iv = np.asarray(intervals)
    T = (iv[:, 1] - iv[:, 0]) / RATE
    g = F.centred_variance(F.flicker_covariance(rec.t[iv[:, 0]], T))
    return np.sqrt(np.maximum(N2[None, :] / T[:, None] + np.maximum(B2, 0)[None, :] * g[:, None], white**2))


def fitted(rec, intervals):
    """N² and B² per axis fitted to the pooled Allan variance of ``intervals`` (floor.py's fit)."""
    iv = np.asarray(intervals)
    n = iv[:, 1] - iv[:, 0]
    m = F.octaves(int(n.max()) // 2)
    avar, count = F.pooled_avar(rec.N, iv, m)
    ok = count / m >= F.MIN_PAIRS
    coef, _, _ = F._fit_axes(m[ok] / RATE, avar[ok], np.repeat((count / m)[ok, None], 3, axis=1))
    return coef[:, 0], coef[:, 1] / F.FLICKER_FACTOR**2


def halves(rec, intervals, u):
    """Half the difference of the two halves' means, along u and across it (per direction), over σ/√n."""
    along, across = [], []
    for (s, e), w in zip(intervals, u):
        h = (e - s) // 2
        y = rec.N[s:s + 2 * h]
        d = (y[:h].mean(0) - y[h:].mean(0)) / 2
        p = y @ w
        q = y - np.outer(p, w)
        along.append((d @ w, p.std(ddof=1) / np.sqrt(2 * h)))
        across.append((np.linalg.norm(d - (d @ w) * w) / np.sqrt(2),
                       np.sqrt(np.sum(q.var(0, ddof=1)) / 2) / np.sqrt(2 * h)))
    a, c = np.array(along), np.array(across)
    return tuple(float(np.sqrt(np.mean(v[:, 0] ** 2) / np.mean(v[:, 1] ** 2))) for v in (a, c))


def simulate(i, intervals, data, seeds, flicker=True):
    """Floor / actual scatter of the means on simulated recordings with recording i's poses and its levels."""
    fl = data.extra["noise_floor"]
    iv = np.asarray(intervals)
    dirs = data.N / np.linalg.norm(data.N, axis=1, keepdims=True)
    hold = (iv[:, 1] - iv[:, 0]) / RATE
    noise_g = float(np.sqrt(np.mean(fl.density**2)) * np.sqrt(RATE) / G0)  # per sample
    flicker_g = float(np.sqrt(np.mean(fl.bias_instability**2)) / G0) if flicker else 0.0
    floor2, actual2 = 0.0, 0.0
    for seed in range(seeds):
        syn = poses_recording(np.random.default_rng(seed), dirs, hold_s=hold, noise_g=noise_g, flicker_g=flicker_g,
                              turn_rate_dps=60.0)
        rec, rests = syn.recording, syn.rests
        f = F.noise_floor(rec.N, rests, rec.t[rests[:, 0]], rec.rate, "g")
        e = np.array([rec.N[s:t].mean(0) for s, t in rests]) - (syn.directions * SCALE + OFFSET)
        e -= e.mean(0)
        floor2 += np.mean(f.sem**2)
        actual2 += np.mean(e**2) * len(e) / (len(e) - 1)
    return float(np.sqrt(floor2 / actual2)), noise_g, flicker_g


def ug(v):
    return f"{v * 1e6:.0f}"


def rms(v):
    return float(np.sqrt(np.mean(np.square(v))))


def run(seeds: int) -> None:
    runs = {i: command(i) for i in range(5)}
    print("| recording | positions, model | residual RMS µg | floor µg | σ/√n µg | floor/(σ/√n) | χ²/dof | p | "
          "scale Δ/SE | offset Δ/SE | angle cosines Δ/SE |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for i, d in runs.items():
        gof = d["goodness_of_fit"]
        (sc, se_k), (off, se_b), (cos, se_c) = ours(d["parameters"], d["stderr"])
        r_sc, r_off, r_cos = source(i)
        pairs = ((sc, r_sc, se_k), (off, r_off, se_b), (cos, r_cos, se_c))
        dev = [float(np.max(np.abs(a - b) / s)) for a, b, s in pairs]
        print(f"| imu{i} | {d['n_positions']}, {d['model']} | {ug(gof['rms_g'])} | {ug(gof['noise_g'])} | "
              f"{ug(gof['white_noise_g'])} | {gof['noise_g'] / gof['white_noise_g']:.2f} | "
              f"{gof['chi2'] / gof['dof']:.3f} | {gof['p_value']:.2f} | {dev[0]:.2f} | {dev[1]:.2f} | {dev[2]:.2f} |")

    print("\n| recording | LOO scatter µg | floor µg | σ/√n µg | along-force σ/√n µg | floor / scatter | "
          "σ/√n / scatter | along σ/√n / scatter |")
    print("|---|---|---|---|---|---|---|---|")
    fits, z = {}, {"floor": [], "white": [], "along": [], "err": []}
    for i, d in runs.items():
        iv = d["recording"]["intervals"]
        rec, data = positions(i, iv)
        cal, err = leave_one_out(data, d["model"])
        fits[i] = (rec, iv, data, cal)
        sig = {"floor": position_sigma(cal.problem, cal.x), "white": white_sigma(cal.problem, cal.x),
               "along": along_sigma(rec, iv, cal.problem, cal.x)}
        for k, v in sig.items():
            z[k].append(err / v)
        z["err"].append(err)
        print(f"| imu{i} | {ug(rms(err))} | {ug(rms(sig['floor']))} | {ug(rms(sig['white']))} | "
              f"{ug(rms(sig['along']))} | " + " | ".join(f"{1 / rms(err / sig[k]):.2f}" for k in sig) + " |")
    print(f"| pooled, {sum(len(e) for e in z['err'])} positions | {ug(rms(np.concatenate(z['err'])))} | | | | "
          + " | ".join(f"{1 / rms(np.concatenate(z[k])):.2f}" for k in ("floor", "white", "along")) + " |")

    print("\n| recording | floor µg: whole intervals | still middles | longest rest alone | per-axis B / along B, "
          "m/s² (turn z) | half-interval along the force / across (×σ/√n) |")
    print("|---|---|---|---|---|---|")
    for i, (rec, iv, data, cal) in fits.items():
        iv = np.asarray(iv)
        fl = data.extra["noise_floor"]
        white = data.std / np.sqrt(data.n_samples)[:, None]
        cut = (iv[:, 1] - iv[:, 0]) // 5
        middles = np.column_stack([iv[:, 0] + cut, iv[:, 1] - cut])
        longest = iv[[int(np.argmax(iv[:, 1] - iv[:, 0]))]]
        res = []
        for part in (middles, longest):
            sem = floor_with(*fitted(rec, part), rec, iv, white)
            problem = CalibrationProblem(cal.model, replace(data, sem=sem), g_local=G_LOCAL, check=False)
            res.append(rms(position_sigma(problem, cal.x)))
        A = cal.problem.specific_force(cal.x)
        u = A / np.linalg.norm(A, axis=1, keepdims=True) / cal.problem._K0
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        al, ac = halves(rec, iv, u)
        turn = ", ".join(f"{'xyz'[k]} {fl.bias_instability[k]:.2g}/{fl.along_bias_instability[k]:.2g} "
                         f"({fl.turn_z[k]:+.1f})" for k in range(3))
        print(f"| imu{i} | {ug(rms(position_sigma(cal.problem, cal.x)))} | {ug(res[0])} | {ug(res[1])} | {turn} | "
              f"{al:.2f} / {ac:.2f} |")

    print(f"\n| recording | simulated white N, flicker B (g per sample, g) | floor / actual scatter | "
          f"with B = 0 | ({seeds} recordings each) |")
    print("|---|---|---|---|---|")
    for i, (_, iv, data, _) in fits.items():
        r, n, b = simulate(i, iv, data, seeds)
        r0, _, _ = simulate(i, iv, data, seeds, flicker=False)
        print(f"| imu{i} | {n * 1e3:.2f} mg, {b * 1e3:.3f} mg | {r:.3f} | {r0:.3f} | |")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    run(ap.parse_args().seeds)
