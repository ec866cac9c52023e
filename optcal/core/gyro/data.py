"""A gyroscope recording cut into rests and the motions between them (Tedaldi et al., ICRA 2014, §IV-B).

Each rest gives the direction of gravity in the body frame (the calibrated accelerometer's mean,
normalised) and the gyroscope's mean output there (its bias, plus g-sensitivity times the rest's specific
force). Each motion is the stretch of samples from the last sample of one rest to the first sample of
the next: integrating the calibrated rate over it must carry the first rest's gravity direction onto the
second's.

The residuals are whitened by their standard deviations, estimated from the rests' sample scatter
(white noise): a rest's mean rate has SD s_W/(K·√n) per axis; a motion's two direction residuals carry
the noise of both rests' gravity directions, s_f/(|f|·√n) each, plus the angle random walk of the
integrated rate, s_W/K·h·√(steps). Noise correlated over the rest (bias instability) is not in them;
the fit's χ² says how well they hold.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from optcal.core.errors import InputError
from optcal.core.ranges import range_means, range_means_sds, range_rows

# A motion must turn the gravity direction by at least this much (rad): below it, the motion carries no
# information on the scale factors and is most likely no motion at all (a rest split in two).
MIN_TURN_RAD = np.deg2rad(5.0)


# A rest is trimmed to where the gyroscope is still: its rate, averaged over STILL_WINDOW_S, within
# STILL_Z standard deviations of that average of the rest's central half.
STILL_WINDOW_S = 0.05
STILL_Z = 5.0


def still_rests(W: np.ndarray, t: np.ndarray, rests: np.ndarray) -> np.ndarray:
    """The rests (r, 2) cut to where the gyroscope is still.

    The accelerometer's detection finds a rest by the specific force, which changes slowly at the start
    and end of a turn; samples of a turn inside a rest would give its first degrees to the rest's gravity
    direction instead of to the integration (a bias of a few 1e-3 rad on a hand-turned 90°). The
    gyroscope sees those samples directly: a sample is still when its rate, as a centred moving average
    over ``STILL_WINDOW_S``, lies within ``STILL_Z`` noise SDs (SD/√window for the average) of the rest's
    level on every axis (the line through the medians of its two halves, so that a slow bias drift is
    not taken for a movement), the noise SD from the median absolute first difference (robust to the
    movement itself); each rest is cut to the span from its first to its last still sample. A movement
    inside a rest is left in it (keeping the longest still run instead cut imu_tk's 50 s initial rest at
    a disturbance and made its first motion worse), so a detector that joins two poses into one rest
    still costs accuracy."""
    from optcal.core.recording.detection import group_medians

    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    w = max(1, int(round(STILL_WINDOW_S / dt)))
    out = rests.copy()
    r = np.asarray(rests, np.int64).reshape(-1, 2)
    if not len(r):
        return out
    a, n = r[:, 0], r[:, 1] - r[:, 0]
    rows, which = range_rows(r)
    j = rows - a[which]  # each sample's place in its rest
    # a slow bias drift over a long rest is not a movement: the level is the line through the two halves' medians
    m1 = group_medians(W, np.column_stack([a, a + n // 2 + 1]))
    m2 = group_medians(W, np.column_stack([a + n // 2, r[:, 1]]))
    s_ = ((j - (n // 2)[which] / 2.0) / np.maximum(n / 2.0, 1.0)[which])[:, None]
    med = m1[which] + (m2 - m1)[which] * s_
    # the noise from each rest's first differences (n − 1 per rest, one after another)
    first = j > 0
    d = W[rows[first]] - W[rows[first] - 1]
    dr = np.column_stack([np.cumsum(n - 1) - (n - 1), np.cumsum(n - 1)])
    md = group_medians(d, dr)
    mad = 1.4826 * group_medians(np.abs(d - np.repeat(md, n - 1, axis=0)), dr) / np.sqrt(2.0)
    c1 = np.concatenate([np.zeros((1, 3)), np.cumsum(d, axis=0)])
    c2 = np.concatenate([np.zeros((1, 3)), np.cumsum(d * d, axis=0)])
    nd = np.maximum(n - 1, 1)[:, None]
    mean_d = (c1[dr[:, 1]] - c1[dr[:, 0]]) / nd
    std_d = np.sqrt(np.maximum((c2[dr[:, 1]] - c2[dr[:, 0]]) / nd - mean_d**2, 0.0))
    sd = np.maximum.reduce([mad, 0.5 * std_d / np.sqrt(2.0), 1e-12 * (1.0 + np.abs(m1))])
    z = (W[rows] - med) / sd[which]
    if w > 1:  # a centred moving average over w samples, zero beyond the rest (np.convolve's "same")
        cz = np.concatenate([np.zeros((1, 3)), np.cumsum(z, axis=0)])
        start = np.repeat(np.cumsum(n) - n, n)  # each rest's first row among the pooled rows
        lo = np.clip(j + (w - 1) // 2 - w + 1, 0, None) + start
        hi = np.minimum(j + (w - 1) // 2 + 1, n[which]) + start
        z = (cz[hi] - cz[lo]) / w
    still = np.all(np.abs(z) < STILL_Z / np.sqrt(w), axis=1)
    # per rest: its still runs (begin, end) among the pooled rows, the first run's start, the last run's end
    prev = np.concatenate([[False], still[:-1]]) & (j > 0)
    nxt = np.concatenate([still[1:], [False]]) & (j < n[which] - 1)
    begins, ends = np.flatnonzero(still & ~prev), np.flatnonzero(still & ~nxt) + 1
    if not len(begins):
        return out
    rest_of = which[begins]
    longest = np.zeros(len(r), np.int64)
    np.maximum.at(longest, rest_of, ends - begins)
    keep = longest >= 2  # else no still run to keep: the rest as detected
    b0 = np.full(len(r), -1)
    e1 = np.full(len(r), -1)
    b0[rest_of[::-1]] = begins[::-1]  # the first run's start (the earliest write wins: written in reverse)
    e1[rest_of] = ends  # the last run's end
    start = np.cumsum(n) - n
    out[keep, 0] = a[keep] + (b0[keep] - start[keep])
    out[keep, 1] = a[keep] + (e1[keep] - start[keep])
    return out


GAP_STEPS = 5.0  # a time step more than this many median steps long is a gap: no motion is integrated across it

# A stretch inside a motion where the gyroscope stays still for at least this long (s), with the accelerometer
# as quiet as in the rests (its sample SD within this factor of theirs), is a pose of its own.
MISSED_REST_MIN_S = 1.0
MISSED_REST_ACC_FACTOR = 3.0


def missed_rests(data: GyroData, min_s: float = MISSED_REST_MIN_S) -> np.ndarray:
    """Rests (q, 2) the accelerometer's detection left inside motions, found by the gyroscope.

    The accelerometer's segmentation may take a pose whose specific force settles slowly (a hand letting go:
    a few noise SDs over seconds) for the end of a motion; the motion then spans two turns and the pose
    between, and integrating through it costs the gyroscope accuracy (on imu_tk's recording two such motions
    carry 2.5° and 3.2°). The gyroscope sees a pose directly: a sample is still as in :func:`still_rests`,
    its rate's moving average over ``STILL_WINDOW_S`` within ``STILL_Z`` noise SDs (the rests' median SD per
    axis, over √window) of the bias level, here interpolated in time between the rests on either side.
    A still run of at least ``min_s`` with moving samples on both sides (not the edge of a rest) and the
    accelerometer's sample SD within :data:`MISSED_REST_ACC_FACTOR` of the rests' on every axis (no
    translation) is returned. ``data``'s rests are not changed; ``data.with_rests`` joins them."""
    t, W, F, r = data.t, data.W, data.F, data.rests
    n = len(t)
    level = np.column_stack([np.interp(t, data.rest_mid_t, data.rest_W[:, i]) for i in range(3)])
    sd = np.maximum(np.median(data.rest_sd_W, axis=0), 1e-300)
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    w = max(1, int(round(STILL_WINDOW_S / dt)))
    z = (W - level) / sd
    if w > 1:
        kernel = np.ones(w) / w
        z = np.column_stack([np.convolve(z[:, i], kernel, mode="same") for i in range(3)])
    # inside a motion: in no rest, and between the first rest's start and the last one's end
    depth = np.zeros(n + 1, np.int64)
    np.add.at(depth, r[:, 0], 1)
    np.add.at(depth, r[:, 1], -1)
    moving = np.cumsum(depth[:n]) == 0
    moving[: r[0, 0]] = False
    moving[r[-1, 1]:] = False
    still = moving & np.all(np.abs(z) < STILL_Z / np.sqrt(w), axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    sd_f = np.median(data.rest_sd_F, axis=0)
    found = []
    min_n = max(2, int(round(min_s / dt)))
    for a, b in zip(edges[0::2], edges[1::2], strict=True):
        if b - a < min_n or not (moving[a - 1] and b < n and moving[b]):
            continue  # too short, or the edge of a rest the detector found (its trimmed end)
        if np.all(F[a:b].std(axis=0, ddof=1) <= MISSED_REST_ACC_FACTOR * sd_f):
            found.append((a, b))
    return np.array(found, np.int64).reshape(-1, 2)


def tangent_basis(u: np.ndarray) -> np.ndarray:
    """Two unit vectors (m, 2, 3) orthogonal to each unit vector of u (m, 3) and to each other."""
    a = np.where(np.abs(u[:, [0]]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    e1 = np.cross(u, a)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(u, e1)
    return np.stack([e1, e2], axis=1)


@dataclass
class GyroData:
    """Samples and their rests. ``t`` (n,) s, ``W`` (n, 3) raw gyroscope outputs in ``units``, ``F`` (n, 3)
    calibrated specific force in g, ``rests`` (r, 2) sample ranges [start, stop) of the static intervals in
    time order, trimmed to where the gyroscope is still (:func:`still_rests`; ``detected_rests`` keeps them
    as given; ``trim_rests`` False takes them as they are). ``saturated`` (n,) marks gyroscope samples at a
    rail: a motion holding one is left out of the motions (``dropped_motions``: its start and end times, s).
    ``missing`` (n,) marks samples without a gyroscope sample (a gap in a second file's samples: their ``W`` is
    not used); a motion holding one, or a gap in the times of more than :data:`GAP_STEPS` steps, cannot be
    integrated either and is left out (``gapped_motions``)."""

    t: np.ndarray
    W: np.ndarray
    F: np.ndarray
    rests: np.ndarray
    units: str = "counts"
    saturated: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
    trim_rests: bool = True
    missing: np.ndarray | None = None

    def __post_init__(self):
        self.t = np.ascontiguousarray(self.t, float)
        self.W = np.ascontiguousarray(self.W, float)
        if self.missing is not None and np.any(self.missing):
            self.missing = np.asarray(self.missing, bool)
            self.W = np.where(self.missing[:, None], 0.0, self.W)  # never integrated: their motions are left out
            self.F = np.where(self.missing[:, None], 0.0, np.asarray(self.F, float))  # (in no rest either)
        self.F = np.ascontiguousarray(self.F, float)
        self.rests = np.asarray(self.rests, np.int64).reshape(-1, 2)
        n = len(self.t)
        if self.W.shape != (n, 3) or self.F.shape != (n, 3):
            raise InputError(f"the gyroscope ({self.W.shape}) and accelerometer ({self.F.shape}) samples must both "
                             f"be (n, 3) with the {n} times; check the columns")
        if not (np.all(np.isfinite(self.t)) and np.all(np.diff(self.t) > 0)):
            raise InputError("the sample times must be finite and strictly increasing; check the time column")
        if not (np.all(np.isfinite(self.W)) and np.all(np.isfinite(self.F))):
            raise InputError("the recording holds NaN or infinite samples; remove them or the rows holding them")
        r = self.rests
        if len(r) < 2:
            raise InputError(f"{len(r)} rest(s) found: a gyroscope calibration needs motions between rests; record "
                             "rests with rotations between them")
        if np.any(r[:, 1] - r[:, 0] < 2) or np.any(r[1:, 0] <= r[:-1, 1] - 1) or r[0, 0] < 0 or r[-1, 1] > n:
            raise InputError("the rests must be ordered, non-overlapping sample ranges of at least 2 samples each")
        self.detected_rests = self.rests
        if self.trim_rests:
            self.rests = still_rests(self.W, self.t, self.rests)
        self._derive()

    def _derive(self) -> None:
        r = self.rests
        nr = np.diff(r, axis=1)[:, 0].astype(float)
        fbar, sd_f = range_means_sds(self.F, r)
        self.rest_W, self.rest_sd_W = range_means_sds(self.W, r)
        self.rest_F = fbar
        self.rest_n = nr
        self.rest_sd_F = sd_f
        self.rest_mid_t = range_means(self.t, r)
        norm = np.linalg.norm(fbar, axis=1)
        if np.any(norm < 0.1):
            raise InputError("a rest's mean specific force is below 0.1 g: the accelerometer columns or its "
                             "calibration are wrong; check them")
        self.u = fbar / norm[:, None]
        # direction noise (rad) of each rest, per tangent component
        self.rest_sd_u = np.sqrt(np.mean(sd_f**2, axis=1) / nr) / norm
        start, stop = r[:-1, 1] - 1, r[1:, 0]
        # a motion during which the gyroscope sits at a rail cannot be integrated: it is left out (the rests on
        # either side still give their bias and gravity direction)
        keep = np.ones(len(start), bool)
        if self.saturated is not None and np.any(self.saturated):
            seen = np.concatenate([[0], np.cumsum(np.asarray(self.saturated, bool))])
            keep = seen[stop + 1] <= seen[start]
        self.dropped_motions = np.column_stack([self.t[start[~keep]], self.t[stop[~keep]]])
        # nor one across a gap: in the times (a logger that paused), or in a second file's gyroscope samples
        dt = np.diff(self.t)
        hole = np.concatenate([[0], np.cumsum(dt > GAP_STEPS * float(np.median(dt)))])  # holes before sample i
        gap = hole[stop] > hole[start]
        if self.missing is not None:
            seen = np.concatenate([[0], np.cumsum(self.missing)])
            gap |= seen[stop + 1] > seen[start]
        gap &= keep
        self.gapped_motions = np.column_stack([self.t[start[gap]], self.t[stop[gap]]])
        keep = keep & ~gap
        self._keep = keep
        self.start = np.ascontiguousarray(start[keep])
        self.stop = np.ascontiguousarray(stop[keep])
        self.u0 = np.ascontiguousarray(self.u[:-1][keep])
        self.u1 = np.ascontiguousarray(self.u[1:][keep])
        self.E = np.ascontiguousarray(tangent_basis(self.u1))
        self.turn = np.arccos(np.clip(np.sum(self.u0 * self.u1, axis=1), -1.0, 1.0))
        self.steps = self.stop - self.start
        h2 = np.array([np.sum(np.diff(self.t[a:b + 1]) ** 2) for a, b in zip(self.start, self.stop, strict=True)])
        self._h2 = h2

    def debiased(self) -> GyroData:
        """The same recording with the bias taken from the rests: each sample minus the rests' mean output,
        interpolated linearly in time between the mid-times of the rests before and after it (held
        constant before the first and after the last). A bias that drifts over the recording (warm-up,
        bias instability) is then followed rest by rest instead of fitted as one constant; it leaves the
        scale factors and misalignments to the motions."""
        offset = np.column_stack([np.interp(self.t, self.rest_mid_t, self.rest_W[:, i]) for i in range(3)])
        out = GyroData(self.t, self.W - offset, self.F, self.rests, units=self.units, saturated=self.saturated,
                       missing=self.missing, extra=dict(self.extra, bias_from_rests=offset,
                                  offset_raw=range_means(offset, self.rests).mean(axis=0)),
                       trim_rests=False)  # trimmed already, by the raw rates
        out.detected_rests = self.detected_rests
        return out

    def centred(self) -> GyroData:
        """The same recording minus one constant, the rests' mean output (``extra["offset_raw"]``): with the
        bias fitted, the bias parameters are then what the rests' mean leaves (rad/s). An unsigned ADC's
        offset (32,768 counts, tens of rad/s for a MEMS gyroscope) would otherwise make a relative change
        of the scale and the bias nearly the same direction, and the observability's relative threshold
        would name them undetermined."""
        offset = np.mean(self.rest_W, axis=0)
        out = GyroData(self.t, self.W - offset, self.F, self.rests, units=self.units, saturated=self.saturated,
                       missing=self.missing, extra=dict(self.extra, offset_raw=offset), trim_rests=False)
        out.detected_rests = self.detected_rests
        return out

    def with_rests(self, extra: np.ndarray) -> GyroData:
        """The same recording with the rests ``extra`` (q, 2) added in time order (trimmed already, as these are;
        e.g. :func:`missed_rests`)."""
        rests = np.concatenate([self.rests, np.asarray(extra, np.int64).reshape(-1, 2)])
        out = GyroData(self.t, self.W, self.F, rests[np.argsort(rests[:, 0])], units=self.units,
                       saturated=self.saturated, missing=self.missing, extra=dict(self.extra), trim_rests=False)
        out.detected_rests = self.detected_rests
        return out

    @property
    def n_motions(self) -> int:
        return len(self.start)

    @property
    def n_rests(self) -> int:
        return len(self.rests)

    def motion_sd(self, K0: np.ndarray) -> np.ndarray:
        """SD (m,) in rad of each motion's two direction residuals, for nominal scale factors K0 (3,)."""
        sw = np.sqrt(np.mean((self.rest_sd_W / K0) ** 2))  # white rate noise per sample, rad/s
        return np.sqrt(self.rest_sd_u[:-1][self._keep] ** 2 + self.rest_sd_u[1:][self._keep] ** 2 + sw**2 * self._h2)

    def rest_sd(self, K0: np.ndarray) -> np.ndarray:
        """SD (r, 3) in rad/s of each rest's mean calibrated rate, for nominal scale factors K0 (3,)."""
        return self.rest_sd_W / K0 / np.sqrt(self.rest_n)[:, None]
