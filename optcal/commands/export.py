"""optcal export: a calibration file's linear part in another tool's format (docs/exchange.md)."""

from __future__ import annotations

NAME = "export"
HELP = "write a calibration's scale, bias and misalignment for another tool: imucal, imu_tk, kalibr or matrix"
FORMATS = ("imucal", "imu_tk", "kalibr", "matrix")  # optcal.exchange.FORMATS, kept here so --help stays light


def add_format_option(p) -> None:
    """``--format``, the same for export and import."""
    p.add_argument("--format", required=True, choices=FORMATS,
                   help="imucal (Ferraris JSON), imu_tk (T, K, B text), kalibr (imu yaml, scale-misalignment) or "
                   "matrix (a = C·raw + d, JSON); docs/exchange.md writes each conversion out")


def add_arguments(p):
    p.add_argument("calibration", metavar="CALIBRATION.json", help="optcal calibration file (optcal calibrate -o)")
    add_format_option(p)
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="the file to write")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.add_argument("--calibrated-units", choices=("g", "m/s2"),
                   help="unit of the calibrated output: imu_tk (default m/s2) and matrix (default g); imucal and "
                   "kalibr are in m/s2")
    p.add_argument("--bias-online", action="store_true",
                   help="kalibr only: export M although the bias is non-zero (Kalibr's yaml has no accelerometer "
                   "bias; Kalibr estimates it online)")


def run(args) -> int:
    from pathlib import Path

    from ..calfile import read_calibration
    from ..errors import InputError
    from ..exchange import export_text
    from ..exchange.common import write_new
    from ._common import check_output_folder, refuse_overwrite, refuse_same_file

    refuse_same_file(args.output, args.calibration)
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    if args.bias_online and args.format != "kalibr":
        raise InputError("--bias-online applies to --format kalibr only")
    if not Path(args.calibration).exists():
        raise InputError(f"{args.calibration} does not exist; give an optcal calibration file (optcal calibrate -o)")
    cal = read_calibration(args.calibration)
    text, notes = export_text(cal, args.format, calibrated=args.calibrated_units, bias_online=args.bias_online,
                              source=args.calibration)
    write_new(args.output, text, force=args.force)
    print(f"wrote {args.output}: {args.calibration} (model {cal.model.name}, raw outputs in {cal.units_out}) in the "
          f"{args.format} format")
    for note in notes:
        print(f"note: {note}")
    return 0
