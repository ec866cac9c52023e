"""The labelled benchmark of rest detection (issue #29, item 8): rests labelled independently of the detectors
(optcal.core.recording.labels), the simulated hand-held IMU recordings they are checked on (optcal.core.synthetic_imu),
and the acceptance test of the new detection on every labelled real recording: recall ≥ 0.95 of the labelled
rests and precision ≥ 0.99 by sample. docs/scripts/rest_benchmark.py prints the table of docs/segmentation.md
from the same corpus table (LABELLED) and scores.

The real corpus lives beside the project (tests/corpus.py); each folder's README gives the source, licence and
MD5 of every file. Labels come from the gyroscope's stillness where the recording has a gyroscope, and from the
source's own intervals where it gives them:

- imucal (MIT): the labelled session's ``part`` column (its six static parts, back to back with steps, the
  file being cut and joined) and the continuous session's section list (six static sections);
- ImuCalibration, MPU-6050 (MIT): that project's ``static_intervals.csv`` (ends inclusive);
- shen_gesture, MPU-9250 (no licence stated: used here only): a re-run of the source's own detector,
  ``FindFixData.m`` (``derived/intervals_findfixdata_39.json``);
- Hassan & Bao, phone (MIT): the 30 sections ``CombinedAlgorithm.m`` averages (no gyroscope: precision by the
  conservative off-pose rule of optcal.core.recording.labels);
- CK-Explorer (Apache-2.0): the logger's 160 blocks of 100 samples, one pose each, back to back;
- gyroscope only: imu_tk's Xsens MTi (BSD), Mikov et al.'s five MPU-9150 (MIT), sdr_rev2's two logs (no
  licence stated: used here only).

Not labelled (no gyroscope, no intervals of the source): TWLogger's tag and sensor-fusion's two tumbles.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pytest
from corpus import corpus_root

from optcal.core.errors import InputError
from optcal.core.recording import label_intervals, read_recording, segment_static
from optcal.core.recording.labels import RestLabels, gyro_labels, interval_labels, runs, score_rests
from optcal.core.synthetic_imu import TRUE_REST_DEG, handheld_imu


def find_rests(acc, gyro=None, **kw):
    """The new detection (issue #29): segmentation judging stillness on the accelerometer and the gyroscope
    (``gyro``'s rates, or the recording's own gyroscope columns)."""
    return segment_static(acc, gyro=None if gyro is None else gyro.N, **kw)


MIN_STATIC_S = 0.5  # s: labelled rests shorter than this are not counted for recall (the detectors' default)
RECALL_MIN = 0.95
PRECISION_MIN = 0.99
DPS_PER_RADS = 180.0 / np.pi


# == the labelled corpus =====================================================================================
@dataclass
class Case:
    """A real recording with its labels: the accelerometer, the gyroscope (or None) and one or more label sets."""

    name: str  # as the table prints it
    acc: object  # Recording
    gyro: object | None
    labels: dict = field(default_factory=dict)  # labels source -> RestLabels

    @property
    def min_static(self) -> int:
        return max(1, int(round(MIN_STATIC_S * self.acc.rate)))


def _gyro(acc, gyro, units_per_dps):
    return gyro_labels(gyro, acc, units_per_dps=units_per_dps)


def _imucal_labelled(root):
    """imucal's annotated session: 204.8 Hz counts; gyroscope counts at about 16.4 per °/s (imucal's own K_g
    16.2-16.7); the six static parts of its ``part`` column, back to back with steps (the file is cut and
    joined: x_a, x_p, x_rot, y_a, ...)."""
    path = root / "imucal" / "annotated_session.csv"
    acc = read_recording(path, columns="acc_x,acc_y,acc_z", rate=204.8, units="counts", labels="part")
    gyro = read_recording(path, columns="ax=gyr_x,ay=gyr_y,az=gyr_z", rate=204.8, units="counts")
    g = _gyro(acc, gyro, 16.4)
    parts = label_intervals(acc, ["x_p", "x_a", "y_p", "y_a", "z_p", "z_a"]).intervals
    return Case("imucal labelled session", acc, gyro,
                {"gyroscope": g, "source: 6 static parts": interval_labels(parts, len(acc), still=g.still)})


def _imucal_continuous(root):
    """imucal's continuous session: m/s², gyroscope °/s, 102.4 Hz; its section list's six static sections."""
    path = root / "imucal" / "example_ferraris_session.csv"
    acc = read_recording(path, columns="acc_x,acc_y,acc_z", rate=102.4, units="m/s2")
    gyro = read_recording(path, columns="ax=gyr_x,ay=gyr_y,az=gyr_z", rate=102.4, units="volts")
    g = _gyro(acc, gyro, 1.0)
    sec = json.loads((root / "imucal" / "example_ferraris_session_list.json").read_text())
    iv = np.array([[v["start"], v["end"]] for k, v in sec.items() if not k.endswith("_rot")])
    return Case("imucal continuous session", acc, gyro,
                {"gyroscope": g, "source: 6 listed sections": interval_labels(iv, len(acc), still=g.still)})


def _mpu6050(root):
    """ImuCalibration's MPU-6050: int16 counts, 100 Hz (Fs line); gyroscope ±250 °/s, 131 counts per °/s (the
    project's own 1.34e-4 rad/s per count); its static_intervals.csv, ends inclusive."""
    path = root / "mpu6050" / "example_data_calibration.csv"
    acc = read_recording(path, columns="ax,ay,az", units="counts")
    gyro = read_recording(path, columns="ax=gx,ay=gy,az=gz", units="counts")
    g = _gyro(acc, gyro, 131.0)
    iv = np.loadtxt(root / "mpu6050" / "static_intervals.csv", delimiter=",").T.astype(np.int64)
    iv[:, 1] += 1
    return Case("MPU-6050 hand-turned (ImuCalibration)", acc, gyro,
                {"gyroscope": g, "source: static_intervals.csv (10)": interval_labels(iv, len(acc), still=g.still)})


def _xsens(root):
    """imu_tk's Xsens MTi pair: unsigned counts, 100 Hz; the gyroscope at about 4,770 counts per rad/s (the fit
    of tests/test_gyro_xsens.py), 83.3 per °/s."""
    acc = read_recording(root / "imu_tk" / "xsens_acc.mat.gz", units="counts", saturation=65535)
    gyro = read_recording(root / "imu_tk" / "xsens_gyro.mat.gz", units="counts", saturation=65535)
    return Case("Xsens MTi (imu_tk)", acc, gyro, {"gyroscope": _gyro(acc, gyro, 4770.0 / DPS_PER_RADS)})


def _mikov(i):
    def load(root):
        """Mikov et al.'s MPU-9150 imu{i}: m/s² then rad/s, no header, 100 Hz (the source's README)."""
        path = root / "mikov" / f"imu{i}.log.gz"
        acc = read_recording(path, columns="ax=0,ay=1,az=2", rate=100.0, units="m/s2")
        gyro = read_recording(path, columns="ax=3,ay=4,az=5", rate=100.0, units="volts")
        return Case(f"MPU-9150 imu{i} (Mikov et al.)", acc, gyro, {"gyroscope": _gyro(acc, gyro, 1 / DPS_PER_RADS)})
    return load


def _shen(root):
    """shen_gesture's MPU-9250: t, counts, 100 Hz; gyroscope ±2000 °/s, 16.4 counts per °/s; the 39 rests of the
    source's FindFixData.m, re-run (derived/intervals_findfixdata_39.json, [start, end))."""
    path = root / "shen_gesture" / "caldata.mat"
    acc = read_recording(path, columns="t=0,ax=1,ay=2,az=3", units="counts")
    gyro = read_recording(path, columns="t=0,ax=4,ay=5,az=6", units="counts")
    g = _gyro(acc, gyro, 16.4)
    iv = np.array(json.loads((root / "shen_gesture" / "derived" / "intervals_findfixdata_39.json").read_text()))
    return Case("MPU-9250 hand-held (shen_gesture)", acc, gyro,
                {"gyroscope": g, "source: FindFixData re-run (39)": interval_labels(iv, len(acc), still=g.still)})


def _sdr(which):
    def load(root):
        """sdr_rev2's {which} log: t, m/s², gyroscope in °/s that reads about half the true rate (its README),
        20 Hz."""
        path = root / "sdr_rev2" / f"IMU_Rev2_Data_{which}.txt.gz"
        acc = read_recording(path, columns="t=0,ax=1,ay=2,az=3", units="m/s2")
        gyro = read_recording(path, columns="t=0,ax=4,ay=5,az=6", units="volts")
        return Case(f"rocket IMU {which} (sdr_rev2)", acc, gyro, {"gyroscope": _gyro(acc, gyro, 0.5)})
    return load


# Hassan & Bao, CombinedAlgorithm.m: the 30 sample ranges it averages (1-based, both ends included)
HB_PHONE_SECTIONS = [(1, 335), (377, 641), (824, 1005), (1162, 1508), (1608, 1855), (1922, 2251), (2318, 2608),
                     (2701, 2909), (2977, 3099), (3213, 3323), (3455, 3570), (3651, 3775), (3869, 3959),
                     (4040, 4178), (4221, 4348), (4435, 4519), (4611, 4756), (4855, 4960), (5070, 5116),
                     (5243, 5345), (5425, 5548), (5613, 5736), (5825, 5975), (6082, 6194), (6264, 6377),
                     (6412, 6580), (6663, 6781), (6843, 6955), (7014, 7151), (7216, 7264)]


def _phone(root):
    """Hassan & Bao's phone: m/s², no time and no rate anywhere (50 Hz assumed, as tests/test_corpus.py);
    no gyroscope: precision by the conservative off-pose rule."""
    acc = read_recording(root / "hassan_bao" / "MobileAccData30orientationRawSample01.mat", rate=50.0, units="m/s2")
    iv = np.array([(s - 1, e) for s, e in HB_PHONE_SECTIONS])
    return Case("phone, hand-held (Hassan & Bao; 50 Hz assumed)", acc, None,
                {"source: 30 sections (off-pose rule)": interval_labels(iv, len(acc), outputs=acc.N)})


def _ck(root):
    """CK-Explorer: 160 poses of 100 samples, back to back (no motion was logged); 100 Hz assumed."""
    acc = read_recording(root / "ck_explorer" / "acc_log.csv", rate=100.0, units="g")
    blocks = np.column_stack([np.arange(0, 16000, 100), np.arange(100, 16001, 100)])
    return Case("160 1-s poses back to back (CK-Explorer; 100 Hz assumed)", acc, None,
                {"source: the logger's 160 blocks": interval_labels(blocks, len(acc), outputs=acc.N)})


LABELLED = {
    "imucal_labelled": _imucal_labelled,
    "imucal_continuous": _imucal_continuous,
    "mpu6050": _mpu6050,
    "xsens": _xsens,
    **{f"mikov_imu{i}": _mikov(i) for i in range(5)},
    "shen_gesture": _shen,
    "sdr_long": _sdr("Long"),
    "sdr_short": _sdr("Short"),
    "hassan_bao_phone": _phone,
    "ck_explorer": _ck,
}
# the label sets of each recording, by key (known before the corpus is read: the tests' parameters)
LABEL_SETS = {
    "imucal_labelled": ["gyroscope", "source: 6 static parts"],
    "imucal_continuous": ["gyroscope", "source: 6 listed sections"],
    "mpu6050": ["gyroscope", "source: static_intervals.csv (10)"],
    "xsens": ["gyroscope"],
    **{f"mikov_imu{i}": ["gyroscope"] for i in range(5)},
    "shen_gesture": ["gyroscope", "source: FindFixData re-run (39)"],
    "sdr_long": ["gyroscope"],
    "sdr_short": ["gyroscope"],
    "hassan_bao_phone": ["source: 30 sections (off-pose rule)"],
    "ck_explorer": ["source: the logger's 160 blocks"],
}
UNLABELLED = {  # corpus recordings left out, and why
    "twlogger/T1D0711-00.CSV.gz": "no gyroscope, no intervals of the source",
    "sunsided/full_sphere_accelerometer.mat": "no gyroscope, no intervals of the source",
    "sunsided/tilt_sphere_accelerometer.mat": "no gyroscope, no intervals of the source (a tumble)",
    "hassan_bao/CalibrationOfLowCostTriaxialInertialSensors*.mat": "position means, not a recording",
}


def labelled_corpus(root=None):
    """Every labelled recording of the corpus at ``root`` (default: tests/corpus.py's), as Cases, in order."""
    root = corpus_root() if root is None else root
    return {key: load(root) for key, load in LABELLED.items()}


_CASES: dict = {}


def _case(key) -> Case:
    if key not in _CASES:
        _CASES[key] = LABELLED[key](corpus_root())
    return _CASES[key]


# == the simulator =============================================================================================
def _quat_scan(w_rad: np.ndarray, dt: float) -> np.ndarray:
    """(n, 4) quaternions P_i = q_1 ⊗ … ⊗ q_i of the body-frame increments q_i = exp(½ ω̄_i dt), ω̄_i the mean
    of samples i−1 and i (q_0 = 1): a prefix product in log₂ n vectorised steps (Hillis-Steele)."""
    wm = np.vstack([np.zeros((1, 3)), (w_rad[1:] + w_rad[:-1]) / 2])
    th = np.linalg.norm(wm, axis=1) * dt
    axis = np.where(th[:, None] > 0, wm / np.maximum(np.linalg.norm(wm, axis=1), 1e-300)[:, None], 0.0)
    Q = np.column_stack([np.cos(th / 2), axis * np.sin(th / 2)[:, None]])

    def mul(p, q):
        a, b = p[:, :1], p[:, 1:]
        c, d = q[:, :1], q[:, 1:]
        return np.column_stack([a * c - np.sum(b * d, axis=1, keepdims=True), a * d + c * b + np.cross(b, d)])

    step = 1
    while step < len(Q):
        Q = np.vstack([Q[:step], mul(Q[:-step], Q[step:])])
        step *= 2
    return Q


def _rotate_back(P_a, P_b, v):
    """v (a body-frame vector at sample a) in the body frame at sample b: ΔRᵀ v with ΔR = P_a⁻¹ ⊗ P_b."""
    conj = P_a * np.array([1, -1, -1, -1])
    a, b = conj[0], conj[1:]
    c, d = P_b[0], P_b[1:]
    q = np.concatenate([[a * c - b @ d], a * d + c * b + np.cross(b, d)])  # ΔR
    w, u = q[0], q[1:]
    # ΔRᵀ v: rotate by the conjugate
    u = -u
    return v + 2 * w * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))


@pytest.mark.parametrize("quiet", [True, False])
def test_the_gyroscope_turns_the_accelerometer_gravity(quiet):
    """The simulator's two sensors follow one attitude: the gyroscope's rates (calibrated with the true scale
    and bias) integrated from one hold to the next turn the first hold's gravity direction (the
    accelerometer's mean, calibrated) into the next one's, for every motion but the re-seats without motion,
    within 0.01° without noise or tremor and 0.2° with them (the noise's walk over a motion is a few
    hundredths of a degree)."""
    kw = dict(acc_noise_g=0.0, gyro_noise_dps=0.0, tremor_g=0.0, tremor_dps=0.0, gyro_drift_dps=0.0) if quiet else {}
    worst, n_checked = 0.0, 0
    for seed in range(3):
        s = handheld_imu(np.random.default_rng(seed), **kw)
        W = np.radians((s.gyro.N - s.gyro_bias) / s.gyro_scale)
        A = (s.acc.N - s.acc_offset) / s.acc_scale
        P = _quat_scan(W, 1.0 / s.gyro.rate)
        holds = np.array([(a, b) for k, a, b in s.kinds if k == "hold"])
        for (a0, a1), (b0, b1) in zip(holds[:-1], holds[1:]):
            if np.any((s.steps > a0) & (s.steps <= b0)):
                continue  # the attitude jumped: nothing to integrate
            g1 = A[a0:a1].mean(axis=0)
            g2 = A[b0:b1].mean(axis=0)
            pred = _rotate_back(P[a1 - 1], P[b0], g1 / np.linalg.norm(g1))
            err = np.degrees(np.arccos(np.clip(pred @ g2 / np.linalg.norm(g2), -1, 1)))
            turned = np.degrees(np.arccos(np.clip(g1 @ g2 / np.linalg.norm(g1) / np.linalg.norm(g2), -1, 1)))
            assert turned > 1.0  # a motion changes the gravity direction (mostly tilts)
            worst = max(worst, err)
            n_checked += 1
    assert n_checked >= 40
    assert worst < (0.01 if quiet else 0.2), worst


def test_the_simulator_has_the_hard_cases():
    """Every kind of motion occurs, with truth that says so: re-seats without motion split two true rests with
    no moving sample between; settlings and turns are moving; holds are at rest in spite of the tremor."""
    kinds, steps = set(), 0
    for seed in range(3):
        s = handheld_imu(np.random.default_rng(seed))
        kinds |= {k for k, *_ in s.kinds}
        steps += len(s.steps)
        for k, a, b in s.kinds:
            if k == "hold":
                assert s.still[a:b].all()
                assert np.all(np.linalg.norm(s.rate_dps[a:b], axis=1) < 1.5)  # tremor only
            elif k in ("turn", "ramp", "settle"):
                assert not s.still[a:b].all()
        for st in s.steps:  # back to back: the rests touch
            assert np.any(s.rests[:, 1] == st) and np.any(s.rests[:, 0] == st)
        assert np.all(np.diff(s.rests.ravel()) >= 0)
        length = (s.rests[:, 1] - s.rests[:, 0]) / s.acc.rate
        assert length.min() >= 1.0 and length.max() < 5.6
    assert kinds == {"hold", "turn", "ramp", "reseat", "settle"}
    assert steps >= 3
    with pytest.raises(InputError):
        handheld_imu(np.random.default_rng(0), rate=0.0)


# == the labeller and the scorer on simulated truth ==========================================================
SIM_CASES = {
    "default": {},
    "re-seats": dict(p_reseat=0.8),
    "slow starts": dict(p_ramp=1.0),
    "settling every pose, strong tremor": dict(p_settle=1.0, tremor_dps=1.5, tremor_g=5e-3, p_table=0.0),
    "noisy, 50 Hz": dict(rate=50.0, acc_noise_g=5e-3, gyro_noise_dps=0.2),
}


@pytest.mark.parametrize("case", list(SIM_CASES))
def test_gyroscope_labels_against_the_truth(case):
    """The labeller recalls every true rest (≥ 0.5 s) and what it labels still is still (≥ 0.99 by sample),
    over five seeds; every re-seat without motion is found within 3 samples; it gives up at most 15 % of the
    still samples (its ends are conservative)."""
    for seed in range(5):
        s = handheld_imu(np.random.default_rng(100 + seed), **SIM_CASES[case])
        lab = gyro_labels(s.gyro, s.acc)
        truth = interval_labels(s.rests, len(s.acc), still=s.still, source="truth")
        sc = score_rests(lab.rests, truth, min_static=int(MIN_STATIC_S * s.acc.rate))
        assert sc["recall"] == 1.0, (case, seed, sc)
        assert sc["precision"] >= 0.99, (case, seed, sc)
        lost = 1 - (lab.still & s.still).sum() / s.still.sum()
        assert lost < 0.15, (case, seed, lost)
        steps = lab.info["steps"]
        assert len(steps) == len(s.steps), (case, seed, steps, s.steps)
        assert np.all(np.abs(steps - s.steps) <= 3)


def test_gyroscope_labels_leave_a_still_recording_still(rng):
    """Noise alone (a still gyroscope with a bias, 10 minutes at 100 Hz) moves no sample: one rest."""
    from optcal.core.recording.reading import Recording

    n = 60000
    W = 0.1 * rng.standard_normal((n, 3)) + [0.5, -1.0, 0.3]
    A = 3e-3 * rng.standard_normal((n, 3)) + [0.0, 0.0, 1.0]
    t = np.arange(n) / 100.0
    lab = gyro_labels(Recording(t, W, None, "volts", 100.0, np.zeros(n, bool)),
                      Recording(t, A, None, "g", 100.0, np.zeros(n, bool)))
    assert lab.still.all() and lab.rests.tolist() == [[0, n]]


def test_gyroscope_labels_split_at_a_reseat_not_at_a_knock(rng):
    """A still gyroscope over 20 s at 100 Hz; the accelerometer is knocked at 5 s (0.3 s of vibration, 20 times
    its noise, then back where it was) and re-seated at 12 s (a step of 15 noise SDs that stays): the rest is
    split at the re-seat only, within a few samples of it."""
    from optcal.core.recording.reading import Recording

    n, rate = 2000, 100.0
    t = np.arange(n) / rate
    W = 0.1 * rng.standard_normal((n, 3))
    A = 2e-3 * rng.standard_normal((n, 3)) + [0.0, 0.0, 1.0]
    A[500:530] += 0.04 * rng.standard_normal((30, 3))  # the knock
    A[1200:, 0] += 0.03  # the re-seat
    lab = gyro_labels(Recording(t, W, None, "volts", rate, np.zeros(n, bool)),
                      Recording(t, A, None, "g", rate, np.zeros(n, bool)))
    assert lab.still.all()
    assert len(lab.rests) == 2 and abs(int(lab.rests[0, 1]) - 1200) <= 3, lab.rests


def test_gyroscope_labels_find_a_slow_drift():
    """A hand drifting through 0.6° at 0.3 °/s in the middle of a 10 s hold, below the motion floors (1 °/s):
    the drift moves, the hold on both sides stays still."""
    from optcal.core.recording.reading import Recording

    rng = np.random.default_rng(7)
    n, rate = 1000, 100.0
    w = np.zeros((n, 3))
    w[450:650, 0] = 0.3
    W = w + 0.1 * rng.standard_normal((n, 3))
    t = np.arange(n) / rate
    lab = gyro_labels(Recording(t, W, None, "volts", rate, np.zeros(n, bool)))
    assert not lab.still[500:600].any()
    assert lab.still[:400].all() and lab.still[700:].all()


def test_gyroscope_labels_let_a_wobble_come_back(rng):
    """A hand's wobble out by 0.22° and back within 0.1 s (4.4 °/s, under the motion floors) in a 10-s hold: the
    attitude rule flags its peak, but the attitude after it is where it was before, so the hold stays one rest
    (a flagged sample used to split it)."""
    from optcal.core.recording.reading import Recording

    n, rate = 1000, 100.0
    w = np.zeros((n, 3))
    w[600:605, 0], w[605:610, 0] = 4.4, -4.4
    W = w + 0.1 * rng.standard_normal((n, 3))
    t = np.arange(n) / rate
    lab = gyro_labels(Recording(t, W, None, "volts", rate, np.zeros(n, bool)))
    assert lab.rests.tolist() == [[0, n]] and lab.info["slow_motion_samples"] == 0


def test_a_wobble_comes_back_by_its_rules():
    """``_wobbles_back`` unflags an excursion of at most ``short`` samples inside a still run whose attitude after
    it is within 0.2° of that before it (medians over at least ``short`` samples); not one that stays off, a
    longer one, one touching a motion, or one with too few still samples beside it."""
    from optcal.core.recording.labels import _wobbles_back

    n = 400
    phi = np.zeros((n, 3))
    phi[100:104, 0] = 0.3  # out and back
    phi[204:, 1] = 0.3  # out and staying off: a small turn
    slow = np.zeros(n, bool)
    slow[100:104] = slow[200:204] = True
    slow[300:330] = True  # longer than short
    slow[350:352] = True  # next to a motion
    slow[150:155] = slow[160:163] = True  # two, 5 still samples apart: too few to tell where the pose is
    moving = np.zeros(n, bool)
    moving[352:360] = True
    out = _wobbles_back(slow, moving, phi, short=10, L=100)
    assert not out[100:104].any()
    assert out[200:204].all() and out[300:330].all() and out[350:352].all()
    assert out[150:155].all() and out[160:163].all()
    assert out.sum() == slow.sum() - 4


def test_scores_by_their_rules():
    """Recall: a labelled rest is recalled when the kept intervals attributed to it (each to the labelled rest
    it overlaps most) cover at least half of it; an interval joining two labelled rests counts for one;
    labelled rests shorter than min_static are not counted. Precision: the kept samples labelled still."""
    n = 1000
    still = np.zeros(n, bool)
    still[100:300] = still[300:500] = still[600:700] = still[800:820] = True
    lab = RestLabels(still, np.array([[100, 300], [300, 500], [600, 700], [800, 820]]), "test")
    # one interval joins the first two (back to back): one of them recalled; the third half covered
    sc = score_rests([[110, 490], [600, 650]], lab, min_static=50)
    assert sc["n_labelled"] == 3 and sc["n_recalled"] == 2 and sc["precision"] == 1.0
    # less than half: not recalled; two pieces of one rest add up
    assert score_rests([[600, 649]], lab, min_static=50)["n_recalled"] == 0
    assert score_rests([[600, 630], [640, 665]], lab, min_static=50)["n_recalled"] == 1
    # 20 kept samples on motion out of 220: precision 0.909; the short rest counts for precision, not recall
    sc = score_rests([[100, 300], [500, 520], [800, 820]], lab, min_static=50)
    assert sc["n_recalled"] == 1 and abs(sc["precision"] - 220 / 240) < 1e-12
    assert np.isnan(score_rests([], lab, min_static=50)["precision"])
    assert score_rests([], lab, min_static=50)["recall"] == 0.0


def test_interval_labels_without_a_gyroscope_call_moving_only_what_moved():
    """Sections shorter than the true rests (the source's, chosen inside its poses): the off-pose rule calls
    moving the turns between them, and none of the true rest's samples outside the sections (within the
    output noise of the pose); the truth's own rests then score precision 1 against it."""
    s = handheld_imu(np.random.default_rng(3), p_reseat=0.0, p_settle=0.0)
    short = s.rests + np.array([50, -20])  # sections inside the rests
    lab = interval_labels(short, len(s.acc), outputs=s.acc.N)
    between = np.zeros(len(s.acc), bool)
    between[s.rests[0, 0]:s.rests[-1, 1]] = True
    moving_truth = ~s.still & between
    assert (~lab.still)[moving_truth].mean() > 0.8
    assert lab.still[s.still].mean() > 0.995
    sc = score_rests(s.rests, lab, min_static=50)
    assert sc["recall"] == 1.0 and sc["precision"] > 0.995


# == the real corpus: the new detection against the labels =====================================================
# Where the detection does not yet meet the targets (measured with docs/scripts/rest_benchmark.py; recall,
# precision by sample): strict expected failures, each naming why, so that a fix shows as an unexpected pass.
SHORT_OF_TARGET = {
    ("mpu6050", "gyroscope"): "recall 0.750, precision 0.9887: hand-held poses of 0.5-0.7 s that sway at 1-2 °/s, "
                              "their attitude at the 0.2° line",
    ("mpu6050", "source: static_intervals.csv (10)"): "recall 0.857, precision 0.9887 (by the gyroscope's labels): "
                                                       "the same sway",
}


def _params():
    out = []
    for key, sets in LABEL_SETS.items():
        for src in sets:
            why = SHORT_OF_TARGET.get((key, src))
            marks = () if why is None else pytest.mark.xfail(strict=True, reason=why)
            out.append(pytest.param(key, src, id=f"{key}-{src.split(':')[0]}", marks=marks))
    return out


@pytest.mark.usefixtures("corpus")
@pytest.mark.parametrize("key,source", _params())
def test_find_rests_on_the_labelled_corpus(key, source):
    """Issue #29: recall ≥ 0.95 of the labelled rests (≥ 0.5 s) and precision ≥ 0.99 by sample, on every
    labelled real recording, for the new detection with its defaults (the gyroscope given where there is one)."""
    case = _case(key)
    found = find_rests(case.acc, case.gyro).intervals
    sc = score_rests(found, case.labels[source], min_static=case.min_static)
    assert sc["recall"] >= RECALL_MIN and sc["precision"] >= PRECISION_MIN, sc


@pytest.mark.usefixtures("corpus")
def test_the_detections_gyroscope_scale_on_the_corpus(monkeypatch):
    """The scale the slow-motion rule works in (attitude.gyro_scale, fitted to the rotations of gravity) is each
    corpus gyroscope's declared sensitivity within 2 % (measured: 0.990-1.009), where the bound alone was up to
    19 % above it (the hand-turned MPU-6050); on imucal's labelled session, whose few turns are about gravity and
    joined where the recording was cut, the fit explains nothing and the bound stands (4.0 times)."""
    import optcal.core.recording.attitude as attitude
    import optcal.core.recording.segment as segment

    seen = {}

    def scale(X, M, A, rests, turning, rate):
        seen["fit"] = attitude.gyro_scale(X, M, A, rests, turning, rate)
        seen["bound"] = attitude.scale_bound(M, A, rests, turning, rate)
        return seen["fit"]

    monkeypatch.setattr(segment, "gyro_scale", scale)
    ratios = {}
    for key in LABELLED:
        case = _case(key)
        lab = case.labels[LABEL_SETS[key][0]]
        if case.gyro is None:
            continue
        seen.clear()
        find_rests(case.acc, case.gyro)
        true = lab.info["units_per_dps"] * 180.0 / np.pi
        ratios[key] = (seen["fit"] / true, seen["bound"] / true)
    fits = {k: f for k, (f, b) in ratios.items() if k != "imucal_labelled"}
    assert all(0.98 <= f <= 1.02 for f in fits.values()), ratios
    assert ratios["mpu6050"][1] > 1.15
    assert ratios["imucal_labelled"][0] == ratios["imucal_labelled"][1] > 3.5


@pytest.mark.usefixtures("corpus")
def test_the_labelled_corpus_is_the_corpus():
    """Every corpus folder is labelled or said why not; each label set holds rests."""
    root = corpus_root()
    folders = {p.name for p in root.iterdir() if p.is_dir()}
    covered = {"imucal", "mpu6050", "imu_tk", "mikov", "shen_gesture", "sdr_rev2", "hassan_bao", "ck_explorer"}
    assert folders <= covered | {k.split("/")[0] for k in UNLABELLED}, folders
    for key in LABELLED:
        case = _case(key)
        assert list(case.labels) == LABEL_SETS[key]
        for lab in case.labels.values():
            long = np.sum(lab.rests[:, 1] - lab.rests[:, 0] >= case.min_static)
            assert long >= 6, (key, long)


def test_true_rest_tolerance_is_under_the_accelerometer_noise():
    """The truth's tolerance (0.1°) moves the gravity direction by 1.7 mg, under the simulated accelerometer's
    2-5 mg noise of a sample; the hold's tremor stays within it."""
    assert np.radians(TRUE_REST_DEG) < 2e-3
    s = handheld_imu(np.random.default_rng(0))
    for k, a, b in s.kinds:
        if k == "hold" and b - a > 10:
            g = s.gravity[a:b]
            ang = np.degrees(np.arccos(np.clip(g @ g.mean(axis=0) / np.linalg.norm(g.mean(axis=0)), -1, 1)))
            assert ang.max() < TRUE_REST_DEG


def test_runs():
    assert runs(np.array([0, 1, 1, 0, 1], bool)).tolist() == [[1, 3], [4, 5]]
    assert runs(np.zeros(3, bool)).shape == (0, 2)
