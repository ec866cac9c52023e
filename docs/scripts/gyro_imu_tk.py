"""The gyroscope of imu_tk's Xsens MTi recording, calibrated by optcal, beside imu_tk's own result.

The recordings are read from the real corpus (tests/corpus.py: ``OPTCAL_CORPUS``, else the shared folder beside
the clone); imu_tk's own figures below are constants, printed by its test_imu_calib on the same two files.

Reproduce:

    .venv/bin/python docs/scripts/gyro_imu_tk.py     # tables on stdout, JSON to out/gyro_imu_tk_{rests,fit}.json

The accelerometer is calibrated first (linear9, local gravity 9.81744 m/s² as imu_tk's test program
sets, threshold searched as ``optcal calibrate`` does); its rests and its calibrated specific force are
the gyroscope's reference. The gyroscope is fitted with scipy-lm, its standard errors from the
Cramér-Rao bound of the whitened residuals, Birge-scaled by √(χ²/dof) when the fit's χ²/dof exceeds 1.
"""

from __future__ import annotations

import gzip
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
from corpus import corpus_root  # noqa: E402  tests/corpus.py: the real corpus's folder (OPTCAL_CORPUS or beside the clone)

DATA = corpus_root() / "imu_tk"
G_SITE = 9.81744  # m/s², imu_tk's test_imu_calib.cpp

# imu_tk's output on this pair (its own test_imu_calib run on xsens_acc.mat and xsens_gyro.mat; docs/gyroscope.md
# §5): the gyroscope's misalignment matrix, scale matrix (rad/s per count) and bias (counts).
IMU_TK_MIS = np.array([[1.0, 0.00593634, 0.00111101], [0.00808812, 1.0, -0.0535569],
                       [0.0253067, -0.0025513, 1.0]])
IMU_TK_SCALE = np.array([0.000209295, 0.000209899, 0.000209483])
IMU_TK_BIAS = np.array([32777.1, 32459.8, 32511.8])
# and its accelerometer calibration of the same run (misalignment, scale in m/s² per count, bias in counts):
# the body frame its gyroscope misalignments refer to.
IMU_TK_ACC_MIS = np.array([[1.0, -0.0033593, -0.00890639], [0.0, 1.0, -0.0213341], [0.0, 0.0, 1.0]])
IMU_TK_ACC_SCALE = np.array([0.00241278, 0.00242712, 0.00241168])
IMU_TK_ACC_BIAS = np.array([33124.2, 33275.2, 32364.4])


def imu_tk_matrix() -> np.ndarray:
    """imu_tk's calibration matrix: ω = Mis·diag(S)·(W − bias), rad/s per count."""
    return IMU_TK_MIS @ np.diag(IMU_TK_SCALE)


def frame_rotation(N_rest: np.ndarray, F_rest: np.ndarray) -> np.ndarray:
    """The rotation R (3, 3) from optcal's accelerometer frame to imu_tk's: the rests' gravity directions
    calibrated by optcal (``F_rest``) and by imu_tk's accelerometer calibration (of the raw means
    ``N_rest``) aligned in the least-squares sense (Kabsch, through scipy's align_vectors)."""
    from scipy.spatial.transform import Rotation

    theirs = (IMU_TK_ACC_MIS @ np.diag(IMU_TK_ACC_SCALE) @ (N_rest - IMU_TK_ACC_BIAS).T).T
    theirs /= np.linalg.norm(theirs, axis=1, keepdims=True)
    ours = F_rest / np.linalg.norm(F_rest, axis=1, keepdims=True)
    rot, _ = Rotation.align_vectors(theirs, ours)
    return rot.as_matrix()


def calibrate_xsens(bias: str = "rests", g_sensitivity: bool = False) -> dict:
    """optcal's gyroscope calibration of the Xsens pair with the bias mode ``bias`` (``rests`` or ``fit``):
    parameters, the calibration matrix M, the bias in counts (fitted, or the first rest's: the same 50 s
    initial rest imu_tk takes its bias from), their standard errors, and the motions' residual angles
    before and after."""
    from optcal.app.fit import calibrate
    from optcal.app.workflows.recording import choose_threshold
    from optcal.core import analysis
    from optcal.core.gyro import GyroProblem
    from optcal.core.gyro.analysis import check_observable
    from optcal.core.gyro.recording import gyro_data, join_times
    from optcal.core.recording import positions_from_recording, read_recording
    from optcal.solvers.registry import get

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        acc_path, gyro_path = Path(tmp) / "xsens_acc.mat", Path(tmp) / "xsens_gyro.mat"
        acc_path.write_bytes(gzip.decompress((DATA / "xsens_acc.mat.gz").read_bytes()))
        gyro_path.write_bytes(gzip.decompress((DATA / "xsens_gyro.mat.gz").read_bytes()))
        acc = read_recording(acc_path, units="counts", saturation=65535)
        gyr = np.loadtxt(gyro_path)
    join_times(acc.t, gyr[:, 0])
    g = G_SITE / 9.80665
    det = choose_threshold(acc, "linear9", g_local=g)
    cal = calibrate(positions_from_recording(acc, det), "linear9", g_local=g)
    data = gyro_data(acc.t, gyr[:, 1:4], acc.N, det.intervals, "linear9", cal.x, units="counts",
                     rails=(0.0, 65535.0))
    p = GyroProblem(data, g_sensitivity=g_sensitivity, bias=bias)  # nominal scale: the one-dimensional search
    res = get("scipy-lm").solve(p, rng=0, budget=2000)
    x = res.x_full
    obs = check_observable(p, x)
    dof = p.n_residuals - p.model.n_params
    chi2_dof = res.fun / dof
    sd, _ = analysis.crlb(p, x, noise_g=max(1.0, np.sqrt(chi2_dof)))
    K, T, b, _ = (a[0] for a in p.model.matrices(x[None]))
    # optcal's gyroscope in imu_tk's accelerometer frame: ω' = R·ω, so M' = R·M (the misalignments are
    # relative to the accelerometer's frame, which the two tools fix differently)
    N_rest = np.array([acc.N[a:b_].mean(axis=0) for a, b_ in det.intervals])
    R = frame_rotation(N_rest, data.rest_F)
    M = R @ np.linalg.inv(T) / K[None, :]
    # the bias in counts (imu_tk's convention) and its SE by the delta method on K·b
    cov = _covariance(p, x, chi2_dof)
    if p.model.bias:
        J = np.zeros((3, x.size))
        J[:, 0:3] = np.diag(b)
        J[:, p.model.slice_of("bias")] = np.diag(K)
        bias_counts = data_offset(p) + K * b
        se_bias = np.sqrt(np.diag(J @ cov @ J.T))
    else:  # the first rest's mean output and its SE (white noise; Birge-scaled as the rest)
        bias_counts = data.rest_W[0]
        se_bias = data.rest_sd_W[0] / np.sqrt(data.rest_n[0]) * np.sqrt(max(1.0, chi2_dof))
    se_M = _matrix_se(p, x, cov, R)
    r = p.residuals_full(x)[0]
    chi2_parts = (float(np.sum(r[: p.n_motion_residuals] ** 2)), float(np.sum(r[p.n_motion_residuals:] ** 2)))
    before = p.motion_angles(p.centre)
    after = p.motion_angles(x)
    # imu_tk's calibration, evaluated by the same residual (its bias and matrix in optcal's parameters)
    imu_tk_x = _imu_tk_vector(p, R)
    return {"x": x, "names": p.model.names, "sd": sd, "M": M, "se_M": se_M, "bias_counts": bias_counts,
            "se_bias": se_bias, "chi2_dof": chi2_dof, "dof": dof, "rank": obs.rank, "n_rests": data.n_rests,
            "n_motions": data.n_motions, "angles_before": before, "angles_after": after,
            "angles_imu_tk": p.motion_angles(imu_tk_x), "frame_rotation": R, "cost": res.fun, "nfev": res.nfev,
            "solver_s": res.runtime_s, "chi2_motions_rests": chi2_parts, "total_s": time.perf_counter() - t0}


def data_offset(p) -> np.ndarray:
    """The raw offset the problem's data are fitted minus (the bias parameters are the rate beyond it)."""
    return np.asarray(p.data.extra["offset_raw"], float)


def _covariance(p, x, chi2_dof: float) -> np.ndarray:
    J = p.jacobian_full(x)
    return np.linalg.inv(J.T @ J) * max(1.0, chi2_dof)


def _matrix_se(p, x, cov, R) -> np.ndarray:
    """SE (3, 3) of R·M, M = T⁻¹·diag(1/K) (delta method through the model's affine Jacobian; R, fixed by
    40 accelerometer directions to about 3e-5 rad, is taken as exact)."""
    A = np.einsum("ij,jkp->ikp", R, p.model.affine_jacobian(x)[:9].reshape(3, 3, -1)).reshape(9, -1)
    return np.sqrt(np.diag(A @ cov @ A.T)).reshape(3, 3)


def _imu_tk_vector(p, R) -> np.ndarray:
    """optcal's parameters of imu_tk's calibration in optcal's frame: M = Rᵀ·M_imu_tk = T⁻¹·diag(1/K) and
    offset K·b = bias."""
    M = R.T @ imu_tk_matrix()
    Minv = np.linalg.inv(M)  # = diag(K)·T
    K = np.diag(Minv).copy()
    T = Minv / K[:, None]
    x = np.zeros(p.model.n_params)
    x[0:3] = K
    for k, n in enumerate(("T_xy", "T_xz", "T_yx", "T_yz", "T_zx", "T_zy")):
        x[3 + k] = T["xyz".index(n[2]), "xyz".index(n[3])]
    if p.model.bias:
        x[p.model.slice_of("bias")] = (IMU_TK_BIAS - data_offset(p)) / K
    return x


def main() -> int:
    for bias in ("rests", "fit"):
        print(f"## bias: {bias}")
        _table(calibrate_xsens(bias), bias)
    return 0


def _table(out: dict, bias: str) -> None:
    M, se = out["M"], out["se_M"]
    ref = imu_tk_matrix()
    print(f"rests {out['n_rests']}, motions {out['n_motions']}, chi2/dof {out['chi2_dof']:.2f} (motions, rests: "
          f"{out['chi2_motions_rests'][0]:.0f}, {out['chi2_motions_rests'][1]:.0f}), rank {out['rank']}, "
          f"solver {out['solver_s']:.3f} s, whole {out['total_s']:.2f} s")
    print("| cell of M (µrad/s per count) | optcal | SE | imu_tk | difference / SE |")
    print("|---|---|---|---|---|")
    for i in range(3):
        for j in range(3):
            d = (M[i, j] - ref[i, j]) / se[i, j]
            print(f"| M[{'xyz'[i]}{'xyz'[j]}] | {1e6 * M[i, j]:.4f} | {1e6 * se[i, j]:.4f} | "
                  f"{1e6 * ref[i, j]:.4f} | {d:+.1f} |")
    for a in range(3):
        d = (out["bias_counts"][a] - IMU_TK_BIAS[a]) / out["se_bias"][a]
        print(f"| bias {'xyz'[a]} (counts) | {out['bias_counts'][a]:.2f} | {out['se_bias'][a]:.2f} | "
              f"{IMU_TK_BIAS[a]:.1f} | {d:+.1f} |")
    for key in ("angles_before", "angles_after", "angles_imu_tk"):
        v = np.rad2deg(out[key])
        print(f"{key}: median {np.median(v):.3f}°, RMS {np.sqrt(np.mean(v**2)):.3f}°, max {v.max():.3f}°")
    dest = ROOT / "out" / f"gyro_imu_tk_{bias}.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps({k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in out.items()},
                               indent=1))


if __name__ == "__main__":
    sys.exit(main())
