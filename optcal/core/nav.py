"""Static navigation: the position error a calibration causes in a strapdown INS at rest (docs/design.md, "Static
navigation").

The papers judge a calibration by a static navigation run (2020 paper §5.2, Eq. 23, Table 6 and
Figure 11; 2015 paper §7): the accelerometer errors the calibration leaves, seen at a fixed attitude,
drive Schuler oscillations in latitude and longitude.

Model: the linearised strapdown INS error equations in the **phi-angle (true-frame) form** in the local
level **NED** frame for a vehicle at rest on the rotating WGS84 Earth (Titterton & Weston, *Strapdown
Inertial Navigation Technology*, 2nd ed., §12.3-12.4; Savage, *Strapdown Analytics*, §12). With
v = 0 the transport rate vanishes; what is left is the Schuler loop (ω_s² = g/R) and the Earth-rate
(Coriolis and ω_ie × φ) coupling. State ``x = (φ_N, φ_E, φ_D, δv_N, δv_E, δL, δλ)``:

    φ̇_N = −Ω sinL·φ_E − Ω sinL·δL + δv_E/R_E − ε_N
    φ̇_E =  Ω sinL·φ_N + Ω cosL·φ_D − δv_N/R_N − ε_E
    φ̇_D = −Ω cosL·φ_E − Ω cosL·δL − tanL·δv_E/R_E − ε_D
    δv̇_N =  g·φ_E − 2Ω sinL·δv_E + δf_N
    δv̇_E = −g·φ_N + 2Ω sinL·δv_N + δf_E
    δL̇  = δv_N/R_N
    δλ̇  = δv_E/(R_E cosL)

Signs: every error is computed minus true; the computed attitude is Ĉ_b^n = (I − [φ×])·C_b^n;
δf^n = C_b^n·δf^b and ε^n = C_b^n·ε^b are the accelerometer and gyro errors (measured minus true).
R_N and R_E are the WGS84 meridian and prime-vertical radii plus height, g is normal gravity there.
The vertical channel (δv_D, δh) is unstable and the papers' error is horizontal, so it is excluded
(height held, as by a barometric or known-height aid); δf_D therefore has no effect.

The inputs are constant, so ``x' = F x + b`` is solved exactly: with ``M = [[F, b], [0, 0]]`` the
augmented state obeys ``z(t) = expm(M t)·z(0)``; the step Φ_M = expm(M Δt) = [[Φ, Γ·b], [0, 1]] with
Φ = expm(F Δt) and Γ = ∫₀^Δt expm(F s) ds, which are computed once per site and step and cached. On the
grid t_k = k·Δt the states are filled by doubling: ``z[k:k+m] = z[0:m]·(Φ_M^k)ᵀ`` with Φ_M^(2k) =
Φ_M^k·Φ_M^k: one vectorised product per doubling (17 for a day at 1 s), no loop over time steps.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gravity import A_WGS84, E2_WGS84, G0, OMEGA_E, normal_gravity
from optcal.core.model import Context, Model

NMI_M = 1852.0  # international nautical mile, m
DEG_PER_HOUR = math.pi / 180.0 / 3600.0  # rad/s per deg/h
STATES = ("phi_N", "phi_E", "phi_D", "dv_N", "dv_E", "dL", "dlambda")


@dataclass
class NavResult:
    """Latitude/longitude and radial position error of a static run (2020 paper Eq. 23, Table 6)."""

    t_s: np.ndarray
    dlat_rad: np.ndarray
    dlon_rad: np.ndarray
    error_nmi: np.ndarray
    max_error_nmi: float
    mean_error_nmi: float
    hours: float
    latitude_deg: float

    def to_dict(self) -> dict[str, float]:
        """The summary the CLI's ``--json`` prints and a study stores per trial."""
        return {
            "max_error_nmi": self.max_error_nmi,
            "mean_error_nmi": self.mean_error_nmi,
            "hours": self.hours,
            "latitude_deg": self.latitude_deg,
        }


def dcm_body_to_nav(attitude_deg) -> np.ndarray:
    """C_b^n for (roll, pitch, yaw) in degrees: ZYX Euler angles of the FRD body frame against NED.

    At (0, 0, 0) body x points north, y east, z down, so the accelerometer reads f^b = (0, 0, −g).
    """
    att = np.asarray(attitude_deg, float)
    if att.shape != (3,) or not np.all(np.isfinite(att)):
        raise InputError(f"attitude must be three finite angles roll,pitch,yaw in degrees, got {attitude_deg!r}")
    r, p, y = np.radians(att)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
            [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
            [-sp, sr * cp, cr * cp],
        ]
    )


def _check_site(latitude_deg: float, height_m: float) -> None:
    if not np.isfinite(latitude_deg) or abs(latitude_deg) > 89.0:
        raise InputError(
            f"latitude {latitude_deg} deg is outside [-89, 89]; the local-level (NED) error model is singular "
            "at the poles"
        )
    normal_gravity(latitude_deg, height_m)  # validates the height


def radii(latitude_deg: float, height_m: float = 0.0) -> tuple[float, float]:
    """(R_N, R_E): WGS84 meridian and prime-vertical radii of curvature plus height, m."""
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    w = math.sqrt(1.0 - E2_WGS84 * s2)
    return A_WGS84 * (1 - E2_WGS84) / w**3 + height_m, A_WGS84 / w + height_m


def error_dynamics(latitude_deg: float = 45.0, height_m: float = 0.0, earth_rate_coupling: bool = True):
    """F (7×7) of the stationary phi-angle error model (module docstring) and the site constants.

    Returns ``(F, consts)`` with ``consts = dict(g, R_N, R_E, omega_s, Omega)``. With
    ``earth_rate_coupling=False`` Ω is set to zero (Coriolis, ω_ie×φ and the δL terms vanish), leaving
    the bare Schuler loop of the closed-form checks.
    """
    _check_site(latitude_deg, height_m)
    g = normal_gravity(latitude_deg, height_m)
    RN, RE = radii(latitude_deg, height_m)
    lat = math.radians(latitude_deg)
    Om = OMEGA_E if earth_rate_coupling else 0.0
    ws, wc = Om * math.sin(lat), Om * math.cos(lat)
    F = np.zeros((7, 7))
    # φ_N, φ_E, φ_D, δv_N, δv_E, δL, δλ
    F[0, [1, 4, 5]] = -ws, 1.0 / RE, -ws
    F[1, [0, 2, 3]] = ws, wc, -1.0 / RN
    F[2, [1, 4, 5]] = -wc, -math.tan(lat) / RE, -wc
    F[3, [1, 4]] = g, -2.0 * ws
    F[4, [0, 3]] = -g, 2.0 * ws
    F[5, 3] = 1.0 / RN
    F[6, 4] = 1.0 / (RE * math.cos(lat))
    consts = {"g": g, "R_N": RN, "R_E": RE, "omega_s": math.sqrt(g / RN), "Omega": Om}
    return F, consts


def alignment_state(df_n: np.ndarray, eps_n: np.ndarray, latitude_deg: float, g: float,
                    earth_rate_coupling: bool = True) -> np.ndarray:
    """Initial error state after a static self-alignment run to its steady state.

    Levelling makes the computed horizontal specific force zero, f^n×φ + δf^n = 0, so the tilts absorb
    the horizontal accelerometer errors: φ_N = δf_E/g, φ_E = −δf_N/g. Gyrocompassing makes the computed
    east Earth-rate component zero, ε_E − (φ×ω_ie)_E = 0, so φ_D = (ε_E − Ω sinL·φ_N)/(Ω cosL): the east
    gyro bias is absorbed into heading (Titterton & Weston §10.3, the alignment accuracy limits).
    Without Earth-rate coupling there is nothing to gyrocompass on and φ_D = 0.
    """
    x0 = np.zeros(7)
    x0[0] = df_n[1] / g
    x0[1] = -df_n[0] / g
    if earth_rate_coupling:
        lat = math.radians(latitude_deg)
        x0[2] = (eps_n[1] - OMEGA_E * math.sin(lat) * x0[0]) / (OMEGA_E * math.cos(lat))
    return x0


def propagate(F: np.ndarray, b: np.ndarray, x0: np.ndarray, dt: float, n_steps: int) -> np.ndarray:
    """Exact states x(k·dt), k = 0..n_steps, of x' = F x + b (b constant), shape (n_steps+1, n).

    One matrix exponential gives the step of the augmented system, Φ = expm(M·dt) with
    M = [[F, b], [0, 0]]; :func:`_fill` then covers the grid by doubling.
    """
    from scipy.linalg import expm  # here, not at module level: importing optcal stays light

    n = F.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n] = F
    M[:n, n] = b
    return _fill(expm(M * dt), x0, n_steps)


def _fill(P: np.ndarray, x0: np.ndarray, n_steps: int) -> np.ndarray:
    """States on the grid from the augmented step P: z[k:k+m] = z[0:m]·(P^k)ᵀ with P^(2k) = P^k·P^k,
    so a run of n steps costs log2(n) vectorised products and no loop over time steps."""
    n = P.shape[0] - 1
    Z = np.empty((n_steps + 1, n + 1))
    Z[0, :n] = x0
    Z[0, n] = 1.0
    k = 1
    while k <= n_steps:
        m = min(k, n_steps + 1 - k)
        # einsum rather than `@`: multi-threaded BLAS on a tall-skinny product is slower, not faster,
        # on a shared machine, and einsum's plain loop is exact and predictable.
        Z[k : k + m] = np.einsum("kj,ij->ki", Z[:m], P)
        P = P @ P
        k += m
    return Z[:, :n]


@functools.lru_cache(maxsize=64)
def _site_step(latitude_deg: float, height_m: float, earth_rate_coupling: bool, dt: float):
    """(Φ, Γ, consts) for one site and step: Φ = expm(F·dt) and Γ = ∫₀^dt expm(F·s) ds, from one
    exponential of [[F, I], [0, 0]]·dt. Cached, so the runs of a study (one site, many calibrations)
    compute no matrix exponential after the first; the step for input b is [[Φ, Γ·b], [0, 1]]."""
    from scipy.linalg import expm

    F, consts = error_dynamics(latitude_deg, height_m, earth_rate_coupling)
    n = F.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = F
    M[:n, n:] = np.eye(n)
    E = expm(M * dt)
    phi, gamma = E[:n, :n].copy(), E[:n, n:].copy()
    phi.flags.writeable = gamma.flags.writeable = False
    return phi, gamma, consts


def static_navigation(
    f_error_body_ms2,
    *,
    hours: float = 5.0,
    latitude_deg: float = 45.0,
    height_m: float = 0.0,
    attitude_deg=(0.0, 0.0, 0.0),
    gyro_bias_dph=(0.0, 0.0, 0.0),
    earth_rate_coupling: bool = True,
    self_alignment: bool = False,
    dt_s: float | None = None,
) -> NavResult:
    """Latitude, longitude and radial position error of an INS at rest for ``hours``.

    ``f_error_body_ms2``: constant specific-force error (3,) in m/s² in the body frame (measured minus
    true); ``gyro_bias_dph``: constant gyro bias (3,) in deg/h, body frame. The attitude (roll, pitch,
    yaw in degrees, FRD body against NED) is known exactly unless ``self_alignment`` runs a static
    self-alignment first (:func:`alignment_state`). ``dt_s``: output spacing, 10 s by default (the run
    length is split into a whole number of steps; the Schuler period is 5063 s, so the maximum on this
    grid is within 2e-5 of the continuous one). The radial error is 2020 paper Eq. 23 on the
    ellipsoid, sqrt((R_N·δL)² + (R_E·cosL·δλ)²), in nautical miles of 1852 m.
    """
    df_b = np.asarray(f_error_body_ms2, float)
    eps_b = np.asarray(gyro_bias_dph, float)
    if df_b.shape != (3,) or not np.all(np.isfinite(df_b)):
        raise InputError(f"specific-force error must be three finite values in m/s², got {f_error_body_ms2!r}")
    if eps_b.shape != (3,) or not np.all(np.isfinite(eps_b)):
        raise InputError(f"gyro bias must be three finite values in deg/h, got {gyro_bias_dph!r}")
    if not (np.isfinite(hours) and 0 < hours <= 24 * 30):
        raise InputError(f"run length {hours} h must be in (0, 720] hours")
    dt = 10.0 if dt_s is None else float(dt_s)
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"output step {dt_s} s must be positive")
    T = hours * 3600.0
    n_steps = max(1, int(round(T / dt)))
    if n_steps > 2**22:
        raise InputError(f"{n_steps} output steps are too many (at most {2**22}); use a larger dt_s")
    _check_site(latitude_deg, height_m)
    dt = T / n_steps
    phi, gamma, c = _site_step(float(latitude_deg), float(height_m), bool(earth_rate_coupling), dt)
    C = dcm_body_to_nav(attitude_deg)
    df_n = C @ df_b
    eps_n = C @ (eps_b * DEG_PER_HOUR)
    b = np.zeros(7)
    b[:3] = -eps_n
    b[3:5] = df_n[:2]
    x0 = alignment_state(df_n, eps_n, latitude_deg, c["g"], earth_rate_coupling) if self_alignment else np.zeros(7)
    P = np.zeros((8, 8))
    P[:7, :7] = phi
    P[:7, 7] = gamma @ b
    P[7, 7] = 1.0
    X = _fill(P, x0, n_steps)
    dlat, dlon = X[:, 5], X[:, 6]
    coslat = math.cos(math.radians(latitude_deg))
    err = np.hypot(c["R_N"] * dlat, c["R_E"] * coslat * dlon) / NMI_M
    return NavResult(
        t_s=np.linspace(0.0, T, n_steps + 1),
        dlat_rad=dlat,
        dlon_rad=dlon,
        error_nmi=err,
        max_error_nmi=float(err.max()),
        mean_error_nmi=float(err.mean()),
        hours=float(hours),
        latitude_deg=float(latitude_deg),
    )


def _vector(model: Model, x) -> np.ndarray:
    if isinstance(x, dict):
        return model.from_dict(x)
    x = np.asarray(x, float).reshape(-1)
    if x.size != model.n_params:
        raise ValueError(f"parameter vector has {x.size} entries, model {model.name} has {model.n_params}")
    return x


def calibration_error_body(model: Model, x_true, x_est, attitude_deg=(0.0, 0.0, 0.0), latitude_deg: float = 45.0,
                           height_m: float = 0.0, ctx: Context | None = None) -> np.ndarray:
    """Residual specific-force error (3,) in m/s², body frame, that calibration ``x_est`` leaves.

    The truth specific force at the fixed attitude is f^b = C_n^b·(0, 0, −g) with g the normal gravity
    of the site; the sensor's outputs are generated with the true parameters (``model.forward``) and
    converted back with the estimated ones (``model.inverse``); the result is that minus f^b. For a
    bias error only (diag6, equal K) it is −(b_est − b_true)·g0: the model's biases are in g (docs/design.md, "Terms
    and parameters").
    ``x_true``/``x_est``: parameter vectors of ``model`` or {name: value} dicts.
    """
    _check_site(latitude_deg, height_m)
    xt, xe = _vector(model, x_true), _vector(model, x_est)
    g = normal_gravity(latitude_deg, height_m)
    f_b = dcm_body_to_nav(attitude_deg).T @ np.array([0.0, 0.0, -g])
    A = (f_b / G0)[None, :]
    N = model.forward(xt[None, :], A, ctx)
    A_est = model.inverse(xe[None, :], N, ctx)[0, 0]
    return (A_est - A[0]) * G0


def navigation_error(model: Model, x_true, x_est, **kw) -> NavResult:
    """The static-navigation error of one calibration: :func:`calibration_error_body` fed to
    :func:`static_navigation`. ``attitude_deg``, ``latitude_deg``, ``height_m`` go to both, ``ctx`` to
    the first, every other keyword to the second. This is the per-trial metric of a study."""
    site = {k: kw[k] for k in ("attitude_deg", "latitude_deg", "height_m") if k in kw}
    ctx = kw.pop("ctx", None)
    df = calibration_error_body(model, x_true, x_est, ctx=ctx, **site)
    return static_navigation(df, **kw)


def plot_navigation(results: dict[str, NavResult], path, title: str | None = None) -> None:
    """Latitude/longitude error (arc-seconds) and radial error (nmi) over time, one line per result."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for label, r in results.items():
        h = r.t_s / 3600.0
        axes[0].plot(h, np.degrees(r.dlat_rad) * 3600.0, label=label)
        axes[1].plot(h, np.degrees(r.dlon_rad) * 3600.0, label=label)
        axes[2].plot(h, r.error_nmi, label=f"{label} (max {r.max_error_nmi:.3g}, mean {r.mean_error_nmi:.3g})")
    axes[0].set_ylabel("δL, arcsec")
    axes[1].set_ylabel("δλ, arcsec")
    axes[2].set_ylabel("position error, nmi")
    axes[2].set_xlabel("time, h")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[2].legend(fontsize=8)
    if title:
        axes[0].set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
