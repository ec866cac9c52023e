"""optcal noise: white-noise density, bias instability and bias random walk of a static recording, from
its overlapping Allan deviation (the method and its references: optcal/core/noise/; docs/noise.md), for the
accelerometer and, with --gyro-units, the gyroscope (its columns read as optcal imu reads them). The figure
is optcal.core.plots.noise's (the accelerometer's)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from optcal.app.commands._common import refuse_overwrite, refuse_same_file
from optcal.app.commands._dataopts import gyro_units_arg
from optcal.core.errors import InputError

HELP = ("noise of a static recording from its Allan deviation: white-noise density, bias instability, "
        "bias random walk, of the accelerometer and the gyroscope; Kalibr's imu.yaml")
GYRO_UNITS = ("counts", "deg/s", "rad/s", "volts")  # optcal.core.gyro.calfile.GYRO_UNITS, kept here so --help stays
                                                    # light


def add_arguments(p):
    p.add_argument("recording", metavar="RECORDING", help="raw recording of the sensor at rest (t, ax, ay, az per "
                   "sample, or ax, ay, az with --rate; as optcal calibrate --raw reads it)")
    p.add_argument("--interval", metavar="START:END",
                   help="the static stretch, seconds from the first sample (either may be empty; default the "
                   "whole file)")
    d = p.add_argument_group("reading the recording (as optcal calibrate --raw)")
    d.add_argument("--units", help="output units: g, m/s2, counts, volts, mg (default: as the columns' names give "
                   "them, e.g. ax(g) or Acc X [m/s^2]; else g)")
    d.add_argument("--columns", help="columns by name or 0-based index: t,ax,ay,az or ax,ay,az (with --rate), "
                   "or role=column items (default: from the header)")
    d.add_argument("--rate", type=float, metavar="HZ", help="sample rate when the recording has no time column "
                   "(and no Fs line)")
    d.add_argument("--topic", metavar="NAME[,GYRO]", help="a ROS bag's or PX4 ULog's IMU topic (default: its one IMU "
                   "topic); ACC,GYRO for sensors on topics of their own")
    d.add_argument("--scale", type=float, metavar="UNITS_PER_G", help="output units per g, for counts or volts "
                   "(default: the magnitude of the mean output, as a static sensor reads 1 g)")
    g = p.add_argument_group("the gyroscope (its columns as optcal imu reads them)")
    g.add_argument("--gyro-units", choices=GYRO_UNITS, type=gyro_units_arg, help="the gyroscope's output units: "
                   "analyse the gyroscope too (columns from --gyro-columns, --gyro, or RECORDING's header: gx, gyr_x, "
                   "...)")
    g.add_argument("--gyro", metavar="FILE", help="the gyroscope's samples in a second file with the same times "
                   "(t, gx, gy, gz per row, or as --gyro-columns names them)")
    g.add_argument("--gyro-columns", metavar="SPEC", help="the gyroscope's columns by name or 0-based index: "
                   "gx,gy,gz in RECORDING, or t,gx,gy,gz in --gyro")
    g.add_argument("--gyro-scale", type=float, metavar="PER_RAD_S", help="output units per rad/s: required for "
                   "counts and volts (the nominal or calibrated scale, e.g. K of optcal imu); exact for deg/s, rad/s")
    a = p.add_argument_group("analysis")
    a.add_argument("--tau-max", type=float, metavar="S", help="longest averaging time τ, s (default: a quarter of "
                   "the stretch)")
    a.add_argument("--ci", type=float, default=0.683, metavar="LEVEL",
                   help="confidence level of the intervals (default 0.683, one sigma)")
    o = p.add_argument_group("output")
    o.add_argument("--json", action="store_true", help="print the analysis as one JSON object (units in the keys)")
    o.add_argument("--plot", metavar="FILE.png", help="write the accelerometer's log-log Allan deviation figure with "
                   "the read lines")
    o.add_argument("--kalibr-yaml", metavar="FILE.yaml",
                   help="write Kalibr's imu.yaml noise fields (noise densities, random walks, update rate; SI): the "
                   "accelerometer's, and the gyroscope's with --gyro-units (optcal export --format kalibr --noise)")
    o.add_argument("--force", action="store_true", help="overwrite existing --plot and --kalibr-yaml files")


def parse_interval(text: str | None) -> tuple[float | None, float | None]:
    """``--interval START:END`` seconds (either may be empty) → (start, end)."""
    if text is None:
        return None, None
    a, sep, b = str(text).partition(":")
    try:
        if not sep:
            raise ValueError
        start = float(a) if a.strip() else None
        end = float(b) if b.strip() else None
    except ValueError:
        raise InputError(f"--interval {text!r} must be START:END in seconds, e.g. 0:36 (either may be empty)") from None
    if start is not None and end is not None and end <= start:
        raise InputError(f"--interval {text!r}: END must be after START")
    return start, end


def _check_output(path: str | None, force: bool) -> None:
    if not path:
        return
    refuse_overwrite(path, force)
    parent = Path(path).resolve().parent
    if not parent.is_dir():
        raise InputError(f"cannot write {path}: the folder {parent} does not exist")


def gyro_scale(args) -> float | None:
    """The gyroscope's output units per rad/s, or None when the gyroscope is not asked for: --gyro-scale, or
    exact for deg/s and rad/s; gyroscope options without --gyro-units are refused, unless the --gyro-columns
    named say the units (``wx(deg/s)``)."""
    given = [flag for flag, v in (("--gyro", args.gyro), ("--gyro-columns", args.gyro_columns),
                                  ("--gyro-scale", args.gyro_scale)) if v is not None]
    if args.gyro_units is None and args.gyro is None and args.gyro_columns is not None:
        from optcal.core.gyro.recording import units_from_names

        args.gyro_units = units_from_names(args.gyro_columns.split(","))  # AsX(°/s),AsY(°/s),AsZ(°/s): deg/s
    if args.gyro_units is None:
        if given:
            raise InputError(f"{', '.join(given)} need the gyroscope's output units: give --gyro-units "
                             f"({', '.join(GYRO_UNITS)})")
        return None
    if args.gyro_scale is not None:
        if not (math.isfinite(args.gyro_scale) and args.gyro_scale > 0):
            raise InputError(f"--gyro-scale {args.gyro_scale:g} must be a positive number of output units per rad/s")
        return args.gyro_scale
    from optcal.core.gyro.calfile import NOMINAL_SCALE as nominal

    if args.gyro_units not in nominal:
        raise InputError(f"the gyroscope's {args.gyro_units} have no fixed value in rad/s: give --gyro-scale, its "
                         "output units per rad/s (the nominal scale, or K of an optcal imu calibration)")
    return nominal[args.gyro_units]


def gyro_report(args, scale: float, interval):
    """The gyroscope's noise analysis (a NoiseReport with ``sensor`` "gyroscope", samples in rad/s): its
    columns found as optcal imu finds them (--gyro-columns in RECORDING, --gyro a second file sharing its
    times, or the gyroscope's columns RECORDING's header names), then the same stretch and analysis as the
    accelerometer's."""
    from types import SimpleNamespace

    from optcal.app.commands.imu import gyro_recording
    from optcal.core.gyro.recording import join_times
    from optcal.core.noise import noise_from_recording
    from optcal.core.recording.reading import read_recording

    acc = read_recording(args.recording, args.columns, args.rate, args.units, topic=args.topic)
    if args.gyro is None and acc.reading.get("topic") is not None:  # a ROS bag or a ULog: its units are rad/s
        from optcal.core.recording.robotlogs import check_gyro_units

        check_gyro_units(args.recording, args.gyro_units)
    if args.gyro is not None or args.gyro_columns is not None:
        how = SimpleNamespace(gyro=args.gyro, gyro_columns=args.gyro_columns, gyro_units=args.gyro_units,
                              rate=args.rate, time_unit=None, data=args.recording)
        gyr = gyro_recording(how, acc)
        if args.gyro is not None:
            join_times(acc.t, gyr.t)
        columns = gyr.columns
    elif acc.W is not None:
        columns = {r: acc.columns[c] for r, c in (("t", "t"), ("ax", "gx"), ("ay", "gy"), ("az", "gz"))
                   if c in acc.columns}
    else:
        raise InputError(f"--gyro-units asks for the gyroscope's noise, but {args.recording}'s header names no "
                         "gyroscope columns; name them with --gyro-columns gx,gy,gz, or give the second file with "
                         "--gyro")
    # the gyroscope's columns read in the accelerometer's roles; "volts" only labels the samples (the reader
    # checks no magnitude for it), the scale turns them into rad/s
    # a time-of-day column is read by name only where no columns are given: its seconds come as the rate's
    from optcal.core.recording.clock import CLOCK_TIME

    clock = args.gyro is None and acc.reading.get("time_unit") == CLOCK_TIME
    roles = ("ax", "ay", "az") if clock else ("t", "ax", "ay", "az")
    spec = ",".join(f"{role}={col}" for role, col in columns.items() if role in roles)
    report = noise_from_recording(args.gyro or args.recording, columns=spec, rate=acc.rate if clock else args.rate,
                                  units="volts", interval=interval, scale=scale, ci=args.ci, tau_max_s=args.tau_max,
                                  topic=None if args.gyro else args.topic)
    report.sensor, report.units = "gyroscope", args.gyro_units
    report.scale_source = "--gyro-scale" if args.gyro_scale is not None else f"{args.gyro_units}, exact"
    return report


def run(args) -> int:
    from optcal.core.noise import noise_from_recording

    for path, option in ((args.plot, "--plot"), (args.kalibr_yaml, "--kalibr-yaml")):
        refuse_same_file(path, args.recording, args.gyro, option=option)
    _check_output(args.plot, args.force)
    _check_output(args.kalibr_yaml, args.force)
    if not 0 < args.ci < 1:
        raise InputError(f"--ci {args.ci:g} must be a confidence level between 0 and 1, e.g. 0.683")
    for value, option, unit in ((args.scale, "--scale", "output units per g"), (args.tau_max, "--tau-max", "s"),
                                (args.rate, "--rate", "Hz")):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{option} {value:g} must be a positive number of {unit}")
    if args.plot and args.kalibr_yaml and Path(args.plot).resolve() == Path(args.kalibr_yaml).resolve():
        raise InputError("--plot and --kalibr-yaml name the same file")
    fmt = None
    if args.plot:
        from matplotlib.figure import Figure

        fmt = Path(args.plot).suffix.lstrip(".").lower() or "png"
        supported = Figure().canvas.get_supported_filetypes()
        if fmt not in supported:
            raise InputError(f"--plot {args.plot}: matplotlib cannot write .{fmt} files; use one of "
                             f"{', '.join('.' + k for k in sorted(supported))}")
    scale = gyro_scale(args)
    interval = parse_interval(args.interval)
    report = noise_from_recording(args.recording, columns=args.columns, rate=args.rate, units=args.units,
                                  interval=interval, scale=args.scale, ci=args.ci, tau_max_s=args.tau_max,
                                  topic=args.topic)
    gyro = None if scale is None else gyro_report(args, scale, interval)
    # Everything is rendered before anything is written: a failure leaves no partial output behind.
    files: dict[str, bytes] = {}
    if args.kalibr_yaml:
        files[args.kalibr_yaml] = report.kalibr_yaml(gyro).encode()
    if args.plot:
        files[args.plot] = report.figure_bytes(fmt)
    # each to a temporary file beside it, both complete before either is renamed into place (optcal.core.atomicfile)
    from contextlib import ExitStack

    from optcal.core.atomicfile import EXISTS_OUTPUT, atomic_write

    with ExitStack() as stack:
        for path, content in files.items():
            fh = stack.enter_context(atomic_write(path, overwrite=args.force, binary=True, exists=EXISTS_OUTPUT))
            fh.write(content)
    if args.json:
        print(json.dumps({**report.to_dict(), **({"gyroscope": gyro.to_dict()} if gyro else {})}, indent=2))
        return 0
    print(report.table())
    if gyro is not None:
        print()
        print(gyro.table())
    for path in files:
        print(f"wrote {path}")
    return 0
