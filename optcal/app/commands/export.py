"""optcal export: a calibration file's linear part, and an IMU file's gyroscope, in another tool's format
(docs/exchange.md)."""

from __future__ import annotations

NAME = "export"
HELP = "write a calibration's scale, bias and misalignment for another tool: imucal, imu_tk, kalibr or matrix"
FORMATS = ("imucal", "imu_tk", "kalibr", "matrix")  # optcal.core.exchange.FORMATS, kept here so --help stays light


def add_format_option(p) -> None:
    """``--format``, the same for export and import."""
    p.add_argument("--format", required=True, choices=FORMATS,
                   help="imucal (Ferraris JSON), imu_tk (T, K, B text), kalibr (imu yaml, scale-misalignment) or "
                   "matrix (a = C·raw + d, JSON); docs/exchange.md writes each conversion out")


def add_arguments(p):
    p.add_argument("calibration", metavar="CALIBRATION.json", help="optcal calibration file (optcal calibrate -o, "
                   "or optcal imu -o: its gyroscope goes with it)")
    add_format_option(p)
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="the file to write")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--calibrated-units", choices=("g", "m/s2"),
                   help="unit of the calibrated output: imu_tk (default m/s2) and matrix (default g); imucal and "
                   "kalibr are in m/s2")
    p.add_argument("--bias-online", action="store_true",
                   help="kalibr only: export M although the bias is non-zero (Kalibr's yaml has no accelerometer "
                   "or gyroscope bias; Kalibr estimates them online)")
    p.add_argument("--gyro-output", metavar="FILE", help="imu_tk only: the gyroscope's file (imu_tk keeps the "
                   "gyroscope's T, K, B in a second file); required when the calibration has a gyroscope")
    p.add_argument("--accelerometer-only", action="store_true",
                   help="export the accelerometer alone although the calibration has a gyroscope")
    p.add_argument("--noise", metavar="NOISE.yaml", help="kalibr only: the noise densities and random walks "
                   "(optcal noise --kalibr-yaml, with the gyroscope's) to write into the imu entry")


def run(args) -> int:
    from pathlib import Path

    from optcal.app.commands._common import check_output_folder, refuse_overwrite, refuse_same_file
    from optcal.core.atomicfile import EXISTS_OUTPUT, atomic_write
    from optcal.core.calfile import read_calibration
    from optcal.core.errors import InputError
    from optcal.core.exchange import export_files
    from optcal.core.exchange.common import read_text

    outputs = [p for p in (args.output, args.gyro_output) if p]
    for path in outputs:
        option = "-o" if path == args.output else "--gyro-output"
        refuse_same_file(path, args.calibration, args.noise, option=option)
        refuse_overwrite(path, args.force)
        check_output_folder(path, option)
    if args.gyro_output and Path(args.gyro_output).resolve() == Path(args.output).resolve():
        raise InputError("-o and --gyro-output name the same file; imu_tk's two calibrations need two files")
    for flag, value, fmt in (("--bias-online", args.bias_online, "kalibr"), ("--noise", args.noise, "kalibr"),
                             ("--gyro-output", args.gyro_output, "imu_tk")):
        if value and args.format != fmt:
            raise InputError(f"{flag} applies to --format {fmt} only")
    if not Path(args.calibration).exists():
        raise InputError(f"{args.calibration} does not exist; give an optcal calibration file (optcal calibrate -o)")
    cal = read_calibration(args.calibration)
    has_gyro = isinstance(cal.meta.get("gyroscope"), dict)
    if args.gyro_output and not has_gyro:
        raise InputError(f"{args.calibration} has no gyroscope block; drop --gyro-output")
    if args.accelerometer_only and not has_gyro:
        raise InputError(f"{args.calibration} has no gyroscope block; drop --accelerometer-only")
    if args.gyro_output and args.accelerometer_only:
        raise InputError("--accelerometer-only leaves the gyroscope out; drop --gyro-output")
    if args.format == "imu_tk" and has_gyro and not args.accelerometer_only and not args.gyro_output:
        raise InputError(f"{args.calibration} has a gyroscope, which imu_tk keeps in a second file (as its "
                         "test_imu_gyro.calib): name it with --gyro-output FILE, or pass --accelerometer-only")
    noise = None
    if args.noise:
        from optcal.core.exchange.kalibr import load_noise

        if not Path(args.noise).is_file():
            raise InputError(f"--noise {args.noise} does not exist; give the imu.yaml optcal noise --kalibr-yaml wrote")
        noise = load_noise(read_text(args.noise, "noise yaml"), args.noise)
    text, gyro_text, notes = export_files(cal, args.format, calibrated=args.calibrated_units,
                                          bias_online=args.bias_online, source=args.calibration, noise=noise,
                                          accelerometer_only=args.accelerometer_only)
    # each file through a temporary one renamed into place, and both complete before either is renamed: the
    # pair is written whole or not at all
    gyro_existed = bool(args.gyro_output) and Path(args.gyro_output).exists()
    gyro_done = False
    try:
        with atomic_write(args.output, overwrite=args.force, exists=EXISTS_OUTPUT) as fh:
            fh.write(text)
            if gyro_text is not None:
                with atomic_write(args.gyro_output, overwrite=args.force, exists=EXISTS_OUTPUT) as gh:
                    gh.write(gyro_text)
                gyro_done = True
    except InputError:
        if gyro_done and not gyro_existed:
            Path(args.gyro_output).unlink(missing_ok=True)
        raise
    print(f"wrote {args.output}: {args.calibration} (model {cal.model.name}, raw outputs in {cal.units_out}) in the "
          f"{args.format} format" + (", with its gyroscope" if has_gyro and not args.accelerometer_only
                                     and gyro_text is None else ""))
    if gyro_text is not None:
        print(f"wrote {args.gyro_output}: the gyroscope of {args.calibration} in imu_tk's format")
    for note in notes:
        print(f"note: {note}")
    return 0
