"""optcal apply: turn a raw recording into calibrated specific force with a calibration file, and, with an IMU
file (optcal imu -o), the gyroscope's samples into calibrated angular rate: a table, or, for a ROS bag, a bag of
the same storage with the IMU's messages calibrated (optcal.core.recording.bags.write_calibrated)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from optcal.app.commands._common import check_output_folder, refuse_overwrite, refuse_same_file
from optcal.app.commands._dataopts import add_data_options, flag_names, gravity_from_args
from optcal.core.errors import InputError
from optcal.core.gravity import G0

if TYPE_CHECKING:
    import numpy as np

HELP = ("apply a calibration file to a raw recording: raw outputs -> specific force in g or m/s² (and angular rate "
        "in rad/s with an IMU file)")
OUTPUT_UNITS = {"g": 1.0, "m/s2": G0}


def add_arguments(p):
    p.add_argument("calibration", metavar="CALIBRATION.json", help="calibration file (optcal calibrate -o)")
    p.add_argument("data", metavar="RAW", help="raw recording (CSV or whitespace-separated; see --columns), or a ROS "
                   "bag or PX4 ULog (--topic)")
    p.add_argument("-o", "--output", required=True, metavar="CALIBRATED.csv", help="output CSV; for a ROS bag, a "
                   "name without .csv/.txt is a bag of the same storage (.bag; a ROS 2 bag's folder, or its .mcap "
                   "or .db3 file) with the IMU's messages calibrated and every other topic copied")
    p.add_argument("--output-topic", metavar="NAME[,GYRO]", help="bag output: put the calibrated messages on this "
                   "new topic (ACC,GYRO for two) beside the originals, instead of replacing them")
    p.add_argument("--output-units", choices=tuple(OUTPUT_UNITS), default="g",
                   help="units of the calibrated specific force (default g = 9.80665 m/s²)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    g = p.add_argument_group("the gyroscope (an IMU file from optcal imu; as optcal imu reads it)")
    g.add_argument("--gyro", metavar="FILE", help="the gyroscope's samples in a second file with the same times "
                   "(t, gx, gy, gz per row, or as --gyro-columns names them)")
    g.add_argument("--gyro-columns", metavar="SPEC", help="the gyroscope's columns by name or 0-based index: "
                   "gx,gy,gz in RAW, or t,gx,gy,gz in --gyro (default: columns RAW's header names gx, gy, gz, "
                   "gyr_x, ...; for --gyro its first four columns)")
    add_data_options(p, units_of_calibration=True)


def write_csv(path: Path, columns: dict[str, np.ndarray], fmt: dict[str, str], *, overwrite: bool = True) -> None:
    """A header and one row per sample, streamed (no Python loop over values, no whole-file string) into a
    temporary file beside ``path`` that replaces it only when complete (:mod:`optcal.core.atomicfile`): an
    interrupted apply leaves no partial CSV under the output's name, and an old one as it was."""
    import numpy as np

    from optcal.core.atomicfile import EXISTS_OUTPUT, atomic_write

    names = list(columns)
    M = np.column_stack([np.asarray(columns[c], float) for c in names])
    row = ",".join(fmt[c] for c in names)
    with atomic_write(path, overwrite=overwrite, exists=EXISTS_OUTPUT) as fh:
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, M, fmt=row.split(","), delimiter=",")


def write_bag(args, cal, rec, gyro_note) -> int:
    """The calibrated bag: the input's storage and topics, the IMU's messages with the calibrated specific force
    (m/s², as sensor_msgs/msg/Imu defines it) and, with an IMU file, angular rate (rad/s)."""
    import numpy as np

    from optcal.core.gyro.calfile import read_gyro_block
    from optcal.core.recording.bags import write_calibrated

    has_t = "t" in rec.columns
    gcal = read_gyro_block(cal.meta, args.calibration) if isinstance(cal.meta.get("gyroscope"), dict) else None

    def acc(t, N):
        with np.errstate(all="ignore"):
            return cal.apply(N, temp=None, t=t if has_t else None) * G0

    def gyro(t, W, A):
        return gcal.apply(W, A / G0 if gcal.model.g_sensitivity else None)

    with flag_names():
        done = write_calibrated(args.data, args.output, topic=args.topic, t0_ns=int(rec.reading["first_stamp_ns"]),
                                acc=acc, gyro=None if gcal is None else gyro, output_topic=args.output_topic,
                                overwrite=args.force)
    what = "linear_acceleration (m/s²)" + (", angular_velocity (rad/s)" if gcal is not None else "")
    topics = ", ".join(f"{t} ({done['messages'][t]} messages)" + (f" on {new}" if new != t else "")
                       for t, new in done["topics"].items())
    print(f"applied {args.calibration} (model {cal.model.name}, outputs in {cal.units_out}) to {args.data}; wrote "
          f"{args.output} ({done['format']}): {what} calibrated on {topics}; the other topics copied")
    if cal.forced:
        print(f"note: applying a forced calibration (written with --force-weak although the data did not determine "
              f"it): {'; '.join(cal.forced)}")
    if gyro_note:
        print(f"note: {gyro_note}")
    return 0


TABLE_SUFFIXES = (".csv", ".txt", ".tsv")  # apply's output for a ROS bag is a table when named so, else a bag
# Options of add_data_options that only the static-interval detector reads: apply converts every sample.
DETECTOR_OPTIONS = {"raw": ("--raw", False), "intervals": ("--intervals", None), "labels": ("--labels", None),
                    "init_s": ("--init-s", None), "threshold_k": ("--threshold-k", None),
                    "method": ("--method", None), "window": ("--window", None), "min_static": ("--min-static", None)}
# The median magnitude of the calibrated specific force against the calibration's local gravity: beyond this
# factor either way the data are not in the calibration's units (docs/design.md, "Calibration file").
MAGNITUDE_FACTOR = 4.0


def check_magnitude(cal, N, A, path) -> None:
    """Refuse raw outputs ``N`` that are not in the calibration's units: their specific force ``A`` (g, the
    calibration applied) has a median magnitude more than :data:`MAGNITUDE_FACTOR` from the calibration's
    local gravity (a calibration fitted in counts applied to data in g, ...), naming the units the raw
    outputs look like. The calibrated magnitude, not the raw one, so that offsets (an unsigned ADC's
    mid-scale) do not count."""
    import numpy as np

    from optcal.core.data import guess_units

    with np.errstate(over="ignore", invalid="ignore"):
        med = float(np.median(np.linalg.norm(N, axis=1)))
        got = float(np.median(np.linalg.norm(A, axis=1)))
    if not (np.isfinite(got) and got > 0 and 1 / MAGNITUDE_FACTOR <= got / cal.g_local <= MAGNITUDE_FACTOR):
        looks = guess_units(med)
        hint = f", which looks like {looks}" if looks and looks != cal.units_out else ""
        raise InputError(f"the raw outputs of {path} have a median magnitude of {med:.4g}{hint}, and the calibration, "
                         f"fitted to outputs in {cal.units_out!r}, makes them a median specific force of {got:.4g} g "
                         f"where a sensor reads about {cal.g_local:.4g} g; apply a calibration fitted in the data's "
                         "units")


def gyro_rates(args, cal, rec, A) -> tuple[np.ndarray | None, np.ndarray | None, str | None]:
    """The calibrated angular rate (n, 3) in rad/s of the recording's gyroscope, which samples of the gyroscope
    are saturated, and a note; (None, None, note) when there is nothing to calibrate. The columns are read as
    optcal imu reads them: ``--gyro-columns`` in RAW, or ``--gyro`` a second file sharing its times; else the
    columns RAW's header names as a gyroscope's (gx, gyr_x, ...)."""
    from optcal.core.gyro.calfile import read_gyro_block

    asked = args.gyro is not None or args.gyro_columns is not None
    if not isinstance(cal.meta.get("gyroscope"), dict):
        if asked:
            raise InputError(f"{'--gyro' if args.gyro else '--gyro-columns'} asks for the gyroscope, but "
                             f"{args.calibration} has no gyroscope block; apply an IMU file (optcal imu -o), or "
                             "drop the option")
        if rec.W is not None:
            return None, None, (f"{args.data} has gyroscope columns, but {args.calibration} has no gyroscope "
                                "block: they are not calibrated (optcal imu -o writes an IMU file)")
        return None, None, None
    gcal = read_gyro_block(cal.meta, args.calibration)
    if asked:
        from optcal.app.commands.imu import gyro_recording
        from optcal.core.gyro.recording import join_times

        args.gyro_units, args.units_of_calibration = gcal.units_raw, True
        gyr = gyro_recording(args, rec)
        if args.gyro:
            join_times(rec.t, gyr.t)
        W, saturated = gyr.N, gyr.saturated
    elif rec.W is not None:
        from optcal.core.gyro.recording import check_named_units

        check_named_units(gcal.units_raw, [rec.columns[g] for g in ("gx", "gy", "gz")], args.data)
        W, saturated = rec.W, rec.gyro_saturated
    else:
        return None, None, (f"{args.calibration} has a gyroscope calibration, but {args.data} has no gyroscope "
                            "columns: wrote the accelerometer only (name them with --gyro-columns gx,gy,gz, or "
                            "give the second file with --gyro)")
    # g-sensitivity needs the specific force in g: the accelerometer's calibrated samples
    return gcal.apply(W, A if gcal.model.g_sensitivity else None), saturated, None


def run(args) -> int:
    import numpy as np

    from optcal.core.calfile import read_calibration
    from optcal.core.recording.reading import read_recording
    from optcal.core.recording.robotlogs import check_gyro_units, log_kind

    given = [flag for key, (flag, default) in DETECTOR_OPTIONS.items() if getattr(args, key, default) != default]
    if given:
        raise InputError(f"{', '.join(given)} select static intervals, which apply does not: it converts every "
                         "sample of the recording; drop them")
    kind = log_kind(args.data)
    bag_out = kind == "bag" and Path(args.output).suffix.lower() not in TABLE_SUFFIXES
    if kind == "ulog" and Path(args.output).suffix.lower() not in TABLE_SUFFIXES:
        raise InputError(f"-o {args.output}: apply writes a ULog's calibrated samples as a table, not a ULog; name "
                         "the output .csv")
    if args.output_topic is not None and not bag_out:
        raise InputError("--output-topic names the topic of a calibrated bag; apply writes one for a ROS bag with "
                         "-o not ending .csv or .txt: drop --output-topic")
    refuse_same_file(args.output, args.calibration, args.data, args.gyro)
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    g = gravity_from_args(args)
    cal = read_calibration(args.calibration)
    if args.units is not None and args.units != cal.units_out:
        raise InputError(
            f"the data are declared in {args.units!r} but {args.calibration} was fitted to outputs in "
            f"{cal.units_out!r}; convert the data or drop --units"
        )
    if kind is not None:  # a log's units are its messages': m/s² and rad/s
        if cal.units_out != "m/s2":
            raise InputError(f"{args.data}'s accelerometer is in m/s², but {args.calibration} was fitted to outputs "
                             f"in {cal.units_out!r}; apply a calibration fitted in m/s² (from a log, or --units m/s2)")
        block = cal.meta.get("gyroscope")
        if isinstance(block, dict):
            check_gyro_units(args.data, str(block.get("units", {}).get("raw")))
    try:
        with flag_names():
            # every row as written, at its own time: apply writes one calibrated row per row read
            rec = read_recording(args.data, args.columns, args.rate, cal.units_out, saturation=args.saturation,
                                 need_time="t" in cal.model.needs, adc=args.adc, time_unit=args.time_unit,
                                 topic=args.topic, held=False, even=False)
    except InputError as exc:
        if "looks like" not in str(exc) or args.units is not None:
            raise
        # the data were read in the calibration's units, which the user did not choose: say so
        raise InputError(f"{exc} (apply reads the data in {cal.units_out!r}, the units {args.calibration} was "
                         "fitted to: with data in other units, apply a calibration fitted in those)") from None
    has_t = "t" in rec.columns
    with np.errstate(all="ignore"):  # data in other units may overflow; check_magnitude then says so
        A = cal.apply(rec.N, temp=rec.temp, t=rec.t if has_t else None)
    check_magnitude(cal, rec.N, A, args.data)
    omega, gyro_saturated, gyro_note = gyro_rates(args, cal, rec, A)
    if bag_out:
        return write_bag(args, cal, rec, gyro_note)
    scale = OUTPUT_UNITS[args.output_units]
    cols: dict[str, np.ndarray] = {}
    if has_t or np.isfinite(rec.rate):
        cols["t"] = rec.t
    for j, c in enumerate(("ax", "ay", "az")):
        cols[c] = A[:, j] * scale
    if omega is not None:
        for j, c in enumerate(("wx", "wy", "wz")):
            cols[c] = omega[:, j]
    if rec.temp is not None:
        cols["temp"] = rec.temp
    saturated = rec.saturated if gyro_saturated is None else rec.saturated | gyro_saturated
    if saturated.any():
        cols["saturated"] = saturated.astype(float)
    fmt = {c: "%.10g" for c in cols}
    fmt["saturated"] = "%d"
    write_csv(Path(args.output), cols, fmt, overwrite=args.force)
    norm = np.linalg.norm(A, axis=1)
    rates = "" if omega is None else (f"; wx, wy, wz in rad/s by gyroscope model "
                                      f"{cal.meta['gyroscope']['model']}, outputs in "
                                      f"{cal.meta['gyroscope']['units']['raw']}")
    print(f"applied {args.calibration} (model {cal.model.name}, outputs in {cal.units_out}) to {len(rec)} samples "
          f"of {args.data}; wrote {args.output} (ax, ay, az in {args.output_units}{rates})")
    print(f"median |A| = {np.median(norm):.6f} g (calibration's local gravity {cal.g_local:.6f} g)")
    if cal.forced:
        print(f"note: applying a forced calibration (written with --force-weak although the data did not determine "
              f"it): {'; '.join(cal.forced)}")
    if rec.saturated.any():
        print(f"note: {int(rec.saturated.sum())} saturated sample(s) of the accelerometer are flagged in column "
              "'saturated'")
    if gyro_saturated is not None and gyro_saturated.any():
        print(f"note: {int(gyro_saturated.sum())} saturated sample(s) of the gyroscope are flagged in column "
              "'saturated'")
    if gyro_note:
        print(f"note: {gyro_note}")
    gave_gravity = getattr(args, "gravity_ms2", None) is not None or args.latitude is not None
    if gave_gravity and abs(g - cal.g_local) > 1e-6:
        print(f"note: the local gravity given ({g:.6f} g) differs from the calibration's ({cal.g_local:.6f} g); "
              "the output is specific force and does not depend on it")
    return 0
