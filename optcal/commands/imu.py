"""optcal imu: calibrate an IMU's accelerometer and gyroscope from one multi-position recording.

A command of its own rather than an option of ``calibrate``: it reads two sensors (one file with both,
or two files sharing their times, as imu_tk's data come), fits two problems in turn (the gyroscope's
reference is the calibrated accelerometer), and writes one file with both; ``calibrate`` keeps its
single-sensor options and output unchanged.
"""

from __future__ import annotations

import json

from ..errors import InputError
from ._common import check_output_folder, check_seed, parameter_table, parse_options, refuse_overwrite, refuse_same_file
from ._dataopts import add_data_options, gravity_from_args, load_positions

HELP = "calibrate an IMU's accelerometer and gyroscope from one recording of rests with rotations between them"


def add_arguments(p):
    p.add_argument("data", metavar="DATA", help="raw recording with the accelerometer's columns (and the gyroscope's, "
                   "named by --gyro-columns, unless --gyro gives them in a second file)")
    p.add_argument("--gyro", metavar="FILE", help="the gyroscope's samples in a second file with the same times "
                   "(t, gx, gy, gz per row, or as --gyro-columns names them)")
    p.add_argument("--gyro-columns", metavar="SPEC", help="the gyroscope's columns by name or 0-based index: gx,gy,gz "
                   "in DATA, or t,gx,gy,gz in --gyro (default for --gyro: its first four columns)")
    p.add_argument("--gyro-units", required=True, choices=("counts", "deg/s", "rad/s", "volts"),
                   help="the gyroscope's output units")
    p.add_argument("--gyro-scale", type=float, metavar="PER_RAD_S", help="nominal gyroscope scale, output units per "
                   "rad/s (default: exact for deg/s and rad/s; for counts and volts found from the motions)")
    p.add_argument("--gyro-bias", choices=("rests", "fit"), default="rests", help="the gyroscope's bias: from the "
                   "rests, interpolated between them (follows a drifting bias; default), or fitted as constants")
    p.add_argument("--g-sensitivity", action="store_true", help="also fit the gyroscope's g-sensitivity and keep it "
                   "when a likelihood-ratio test finds it (needs --gyro-bias fit)")
    p.add_argument("--model", help="the accelerometer's model (default as optcal calibrate's: nonlinear12, or the "
                   "richest of linear9 and diag6 the rests determine, said in a note)")
    p.add_argument("--solver", default="lm", help="registered solver for both sensors (default lm)")
    p.add_argument("--option", action="append", metavar="KEY=VALUE", help="solver option (repeatable)")
    p.add_argument("--seed", type=int, default=0, help="seed of the solver's random generator")
    p.add_argument("--budget", type=int, help="evaluation budget of each fit (default: the solver's)")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("-o", "--output", metavar="IMU.json", help="write the calibration file with both sensors")
    p.add_argument("--force", action="store_true", help="overwrite an existing calibration file")
    add_data_options(p)


def _columns(spec: str | None, n: int, option: str) -> list[str] | None:
    if spec is None:
        return None
    parts = [c.strip() for c in spec.split(",")]
    if len(parts) != n or not all(parts):
        raise InputError(f"{option} {spec!r} must name {n} columns separated by commas")
    return parts


def gyro_recording(args, acc_rec):
    """The gyroscope's samples (a Recording whose N holds them) and whether they came from a second file."""
    from ..recording import read_recording

    units = "counts" if args.gyro_units == "counts" else "volts"  # the reader's units only label the samples
    if args.gyro:
        cols = _columns(args.gyro_columns, 4, "--gyro-columns")
        spec = None if cols is None else f"t={cols[0]},ax={cols[1]},ay={cols[2]},az={cols[3]}"
        rec = read_recording(args.gyro, spec, args.rate, units, time_unit=args.time_unit)
        return rec
    cols = _columns(args.gyro_columns, 3, "--gyro-columns")
    if cols is None:
        raise InputError("name the gyroscope's columns in DATA with --gyro-columns gx,gy,gz, or give them in a "
                         "second file with --gyro")
    time = acc_rec.columns.get("t")
    spec = (f"t={time}," if time is not None else "") + f"ax={cols[0]},ay={cols[1]},az={cols[2]}"
    return read_recording(args.data, spec, args.rate, units, time_unit=args.time_unit)


def run(args) -> int:
    import numpy as np  # here: building the command line imports no numpy (tests/test_startup.py)

    from ..calfile import calibration_to_dict
    from ..fit import calibrate
    from ..gyro.calfile import NOMINAL_SCALE, gyro_block, write_imu_calibration
    from ..gyro.data import MISSED_REST_MIN_S, GyroData, missed_rests
    from ..gyro.recording import join_times
    from ..gyro.workflow import calibrate_gyro

    check_seed(args.seed)
    if args.budget is not None and args.budget < 1:
        raise InputError(f"--budget {args.budget} must be a number of evaluations of 1 or more")
    if args.g_sensitivity and args.gyro_bias != "fit":
        raise InputError("--g-sensitivity needs --gyro-bias fit: the rests' outputs hold both the bias and G")
    if args.gyro_scale is not None and not (np.isfinite(args.gyro_scale) and args.gyro_scale > 0):
        raise InputError(f"--gyro-scale {args.gyro_scale} must be a positive number of output units per rad/s")
    refuse_same_file(args.output, args.data, args.gyro)
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    args.raw = True
    g_local = gravity_from_args(args)
    named = args.model is not None
    if not named:  # the rests are found for the default model, as optcal calibrate does
        from ..determination import DEFAULT_MODEL

        args.model = DEFAULT_MODEL
    positions = load_positions(args, args.data)
    det = positions.extra["detection"]
    acc = det.recording
    cal = calibrate(positions, args.model if named else None, solver=args.solver, options=parse_options(args.option),
                    g_local=g_local, seed=args.seed, budget=args.budget)
    gyr = gyro_recording(args, acc)
    join_times(acc.t, gyr.t)
    F = cal.model.inverse(np.asarray(cal.x, float)[None], acc.N)[0]
    data = GyroData(acc.t, gyr.N, F, det.intervals, units=args.gyro_units)
    found = missed_rests(data)
    notes = []
    if len(found):  # poses the accelerometer's detection took for motion: the gyroscope is still there
        data = data.with_rests(found)
        notes.append(f"{len(found)} rest(s) the accelerometer's detection left inside motions were found by the "
                     f"gyroscope (still for {MISSED_REST_MIN_S:g} s or more) and used for the gyroscope only, at t = "
                     + ", ".join(f"{acc.t[a]:.1f}-{acc.t[b - 1]:.1f} s" for a, b in found[:6])
                     + (" …" if len(found) > 6 else ""))
    moving = np.flatnonzero([gyr.saturated[a:b + 1].any() for a, b in zip(data.start, data.stop, strict=True)])
    if moving.size:
        k = int(moving[0])
        raise InputError(f"the gyroscope is saturated during motion {k + 1} (t = {acc.t[data.start[k]]:.2f}-"
                         f"{acc.t[data.stop[k]]:.2f} s): its rotation cannot be integrated; turn the sensor more "
                         "slowly or cut that motion out")
    scale = args.gyro_scale if args.gyro_scale is not None else NOMINAL_SCALE.get(args.gyro_units)
    fit = calibrate_gyro(data, bias=args.gyro_bias, g_sensitivity=args.g_sensitivity, scale=scale,
                         solver=args.solver, options=parse_options(args.option), seed=args.seed, budget=args.budget)
    block = gyro_block(fit.problem, fit.x, fit.stderr, solver=args.solver, observability=fit.observability.to_dict(),
                       g_test=fit.g_test)
    record = calibration_to_dict(cal, units_in="g", units_out=args.units, source=str(args.data))
    if args.output:
        write_imu_calibration(record, block, args.output, overwrite=args.force)
    if args.json:
        print(json.dumps({"accelerometer": {**cal.to_dict(), "units": cal.model.units(positions.units)},
                          "gyroscope": block, "notes": list(cal.notes) + notes + fit.notes}, indent=2))
        return 0
    angles = np.rad2deg(fit.problem.motion_angles(fit.x))
    before = np.rad2deg(fit.problem.motion_angles(fit.problem.centre))
    print(f"accelerometer: model {cal.model.name}, {len(positions)} rests, residual RMS {cal.fit.rms_g * 1e6:.1f} µg")
    print(parameter_table(cal.model.names, cal.x, cal.stderr, units=cal.model.units(positions.units)))
    source = "the rests" if args.gyro_bias == "rests" else "the fit"
    print(f"gyroscope: model {fit.problem.model.name} (bias from {source}), {data.n_motions} motions, χ²/dof "
          f"{fit.chi2_dof:.2f}; motion residual RMS {np.sqrt(np.mean(before**2)):.3f}° at the nominal scale, "
          f"{np.sqrt(np.mean(angles**2)):.3f}° calibrated")
    print("observability: " + fit.observability.describe())
    for note in list(cal.notes) + notes + fit.notes:
        print(f"note: {note}")
    units = block["units"]["parameters"]
    print(parameter_table(fit.problem.model.names, fit.x, fit.stderr, units=units))
    if args.output:
        print(f"wrote {args.output}")
    return 0
