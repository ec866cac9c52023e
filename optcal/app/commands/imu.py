"""optcal imu: calibrate an IMU's accelerometer and gyroscope from one multi-position recording.

A command of its own rather than an option of ``calibrate``: it reads two sensors (one file with both,
or two files sharing their times, as imu_tk's data come), fits two problems in turn (the gyroscope's
reference is the calibrated accelerometer), and writes one file with both; ``calibrate`` keeps its
single-sensor options and output unchanged.
"""

from __future__ import annotations

from optcal.app.commands._common import (
    check_output_folder,
    check_seed,
    parameter_table,
    parse_options,
    refuse_overwrite,
    refuse_same_file,
)
from optcal.app.commands._dataopts import add_data_options, gravity_from_args, gyro_units_arg, load_raw_positions
from optcal.core.errors import InputError

HELP = "calibrate an IMU's accelerometer and gyroscope from one recording of rests with rotations between them"


def add_arguments(p):
    p.add_argument("data", metavar="DATA", help="raw recording with the accelerometer's columns and the gyroscope's "
                   "(named by its header, or by --gyro-columns), unless --gyro gives them in a second file")
    p.add_argument("more_data", nargs="*", metavar="MORE", help="more recordings of the same IMU at the same rate "
                   "(a file per pose or per face, each with its gyroscope's columns), joined in turn to DATA: no "
                   "rest spans two files, no motion is fitted across two")
    p.add_argument("--gyro", metavar="FILE", help="the gyroscope's samples in a second file with the same times "
                   "(t, gx, gy, gz per row, or as --gyro-columns names them)")
    p.add_argument("--gyro-columns", metavar="SPEC", help="the gyroscope's columns by name or 0-based index: gx,gy,gz "
                   "in DATA (default: those its header names, e.g. gx or gyr_x), or t,gx,gy,gz in --gyro (default "
                   "for --gyro: its first four columns)")
    p.add_argument("--gyro-units", choices=("counts", "deg/s", "rad/s", "volts"), type=gyro_units_arg,
                   help="the gyroscope's output units (default: as its columns' names give them, e.g. wx(deg/s); a "
                   "ROS bag's or a ULog's are rad/s)")
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
    p.add_argument("--force-weak", action="store_true", help="write fits the data do not determine (too few rests to "
                   "check the fit, an accelerometer parameter left unobservable, a gyroscope fit the gates refuse) "
                   "instead of refusing them; the file records that they were forced and why (fewer rests than the "
                   "smallest model's parameters, or motions that leave a gyroscope parameter undetermined, have no "
                   "one fit to force: still refused)")
    add_data_options(p)


def gyro_recording(args, acc_rec, path=None):
    """The gyroscope's samples (a Recording whose N holds them), from ``args.gyro`` or the columns
    ``args.gyro_columns`` of ``path`` (default ``args.data``) (:func:`optcal.core.gyro.recording.read_gyro`)."""
    from optcal.core.gyro.recording import read_gyro

    return read_gyro(args.data if path is None else path, acc_rec, gyro=args.gyro, gyro_columns=args.gyro_columns,
                     units=args.gyro_units, rate=args.rate, time_unit=args.time_unit,
                     calibration=getattr(args, "units_of_calibration", False),
                     interpolate=getattr(args, "interpolate_gyro", False))


def run(args) -> int:
    import numpy as np  # here: building the command line imports no numpy (tests/test_startup.py)

    from optcal.app.imu import calibrate_imu, check_imu_options
    from optcal.core.recording.join import join_recordings

    check_seed(args.seed)
    if args.gyro_units is None and args.gyro is None:
        from optcal.core.recording.robotlogs import log_kind

        if log_kind(args.data) is not None:
            args.gyro_units = "rad/s"  # sensor_msgs/Imu and PX4's sensor_gyro define them
    # otherwise, without --gyro-units, the gyroscope's columns' names give them (wx(deg/s)), or it is refused
    if args.budget is not None and args.budget < 1:
        raise InputError(f"--budget {args.budget} must be a number of evaluations of 1 or more")
    check_imu_options(gyro_scale=args.gyro_scale, gyro_bias=args.gyro_bias, g_sensitivity=args.g_sensitivity)
    refuse_same_file(args.output, args.data, *args.more_data, args.gyro)
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    args.raw = True
    args.interpolate_gyro = True  # a gyroscope file with its own times is taken at the accelerometer's
    g_local = gravity_from_args(args)
    named = args.model is not None
    # the rests are found as optcal calibrate finds them (for the default model, as many as its smallest fallback
    # needs), judged on the gyroscope too
    read = {}

    def gyro_of(acc, path):
        gyro = gyro_recording(args, acc, path)
        args.gyro_units = gyro.reading["gyro_units"]
        read.setdefault("gyros", []).append(gyro)
        return gyro

    units_named = args.gyro_units is None
    positions = load_raw_positions(args, args.data, gyro_of)
    # several files: their gyroscopes joined as the loader joined them for the rests (the same arrays)
    gyr = read["gyros"][0] if len(read["gyros"]) == 1 else join_recordings(read["gyros"])
    imu = calibrate_imu(positions, gyr, model=args.model if named else None, solver=args.solver,
                        options=parse_options(args.option), g_local=g_local, seed=args.seed, budget=args.budget,
                        gyro_units=args.gyro_units, gyro_scale=args.gyro_scale, gyro_bias=args.gyro_bias,
                        g_sensitivity=args.g_sensitivity, force_weak=args.force_weak)
    if units_named:  # said, as the reader's other inferences are
        imu.notes.insert(0, f"gyroscope in {args.gyro_units}, as its columns' names give it "
                            f"({', '.join(str(gyr.columns[a]) for a in ('ax', 'ay', 'az'))})")
    cal, fit, data = imu.accelerometer, imu.gyroscope, imu.data
    block = imu.gyro_block()
    if args.output:
        imu.write(args.output, overwrite=args.force, source=str(args.data))
    from optcal.core.recording.report import describe_detection, detection_summary

    detection = positions.extra["detection"]
    if args.json:
        import json

        print(json.dumps({"accelerometer": {**cal.to_dict(), "units": cal.model.units(positions.units)},
                          "gyroscope": block, "notes": imu.notes, "recording": detection_summary(detection)},
                         indent=2))
        return 0
    print(describe_detection(detection))  # the rests both fits use, as optcal calibrate lists them
    angles = np.rad2deg(fit.problem.motion_angles(fit.x))
    before = np.rad2deg(fit.problem.motion_angles(fit.problem.centre))
    gof = cal.fit
    test = (f"; χ²/dof {gof.chi2 / max(gof.dof, 1):.3g} against the means' noise floor (p = {gof.p_value:.2g})"
            if gof.chi2 is not None and gof.p_value is not None else "")
    print(f"accelerometer: model {cal.model.name}, {len(positions)} rests, residual RMS {cal.fit.rms_g * 1e6:.1f} µg"
          + test)
    print(parameter_table(cal.model.names, cal.x, cal.stderr, units=cal.model.units(positions.units)))
    source = "the rests" if args.gyro_bias == "rests" else "the fit"
    print(f"gyroscope: model {fit.problem.model.name} (bias from {source}), {data.n_motions} motions, χ²/dof "
          f"{fit.chi2_dof:.2f}; motion residual RMS {np.sqrt(np.mean(before**2)):.3f}° at the nominal scale, "
          f"{np.sqrt(np.mean(angles**2)):.3f}° calibrated")
    print("observability: " + fit.observability.describe())
    for note in imu.notes:
        print(f"note: {note}")
    print(parameter_table(fit.problem.model.names, fit.x, fit.stderr, units=block["units"]["parameters"]))
    if args.output:
        print(f"wrote {args.output}")
    return 0
