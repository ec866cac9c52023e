"""optcal import: another tool's calibration file (with its gyroscope, when it has one) as an optcal calibration
file (docs/exchange.md)."""

from __future__ import annotations

from optcal.app.commands._dataopts import add_gravity_options, gyro_units_arg
from optcal.app.commands.export import FORMATS, add_format_option  # noqa: F401 - FORMATS: tests check the copy

NAME = "import"
HELP = "read an imucal, imu_tk, kalibr or matrix calibration into an optcal calibration file"
UNITS = ("g", "m/s2", "counts", "volts", "mg")  # optcal.core.data.UNITS, kept here so --help stays light
GYRO_UNITS = ("counts", "deg/s", "rad/s", "volts")  # optcal.core.gyro.calfile.GYRO_UNITS, likewise


def add_arguments(p):
    p.add_argument("file", metavar="FILE", help="the other tool's calibration file")
    add_format_option(p)
    p.add_argument("-o", "--output", required=True, metavar="CALIBRATION.json", help="the optcal calibration file")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--units", choices=UNITS,
                   help="raw output units where the file does not state them: imu_tk (required), imucal with an "
                   "unknown from_acc_unit, kalibr (default m/s2; g or mg if its m/s² were converted from those)")
    p.add_argument("--calibrated-units", choices=("g", "m/s2"),
                   help="imu_tk only: unit of its calibrated output (default m/s2, as imu_tk's g_mag is 9.81)")
    p.add_argument("--gyro", metavar="FILE", help="imu_tk only: its gyroscope's calibration file (imu_tk keeps it "
                   "apart from the accelerometer's; imucal and kalibr files hold both sensors)")
    p.add_argument("--gyro-units", choices=GYRO_UNITS, type=gyro_units_arg,
                   help="the gyroscope's raw units: imu_tk (required with --gyro), imucal with an unknown "
                   "from_gyr_unit, kalibr (default rad/s; deg/s if its rad/s were converted from those)")
    p.add_argument("--model", help="optcal model to hold it: diag6, linear9 or scale+bias+misalignment6 "
                   "(default: the smallest that holds the file exactly)")
    add_gravity_options(p)


def run(args) -> int:
    import json

    from optcal.app.commands._common import check_output_folder, refuse_overwrite, refuse_same_file
    from optcal.app.commands._dataopts import gravity_from_args
    from optcal.core.calfile import read_calibration
    from optcal.core.exchange import import_calibration
    from optcal.core.exchange.common import write_new

    refuse_same_file(args.output, args.file, args.gyro)
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    g = gravity_from_args(args) if (args.gravity_ms2 is not None or args.latitude is not None
                                    or args.height is not None) else None
    doc, notes = import_calibration(args.file, args.format, units=args.units, calibrated=args.calibrated_units,
                                    model=args.model, g_local=g, gyro=args.gyro, gyro_units=args.gyro_units)
    raw = doc["units"]["raw"]
    # read_calibration checks the file before it replaces the output: what optcal writes, optcal can read
    write_new(args.output, json.dumps(doc, indent=2) + "\n", force=args.force, check=read_calibration)
    gyro = doc.get("gyroscope")
    also = f"; gyroscope {gyro['model']}, raw outputs in {gyro['units']['raw']}" if gyro else ""
    print(f"wrote {args.output}: {args.file} ({args.format}) as model {doc['model']}, raw outputs in "
          f"{raw}, g_local {doc['g_local']:.9g} g{also}")
    for note in notes:
        print(f"note: {note}")
    return 0
