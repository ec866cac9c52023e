"""Options shared by every command that reads data (calibrate, discover, apply): the positions CSV or a
raw recording, its units and local gravity. The raw-recording options are turned into the keyword arguments
of :func:`optcal.app.workflows.recording.positions_from_raw` here, and the library's errors, which name those parameters
in backquotes, are given the options' names (:func:`flags`, :func:`flag_names`)."""

from __future__ import annotations

import argparse
import re
from contextlib import contextmanager
from typing import TYPE_CHECKING

from optcal.core.errors import InputError
from optcal.core.gravity import local_gravity_g

if TYPE_CHECKING:
    from optcal.core.data import PositionsData
    from optcal.core.recording.options import RawOptions


def gyro_units_arg(value: str) -> str:
    """``--gyro-units`` as typed: the other spellings of deg/s and rad/s (dps, °/s), as the gyroscope's columns'
    names write them (:data:`optcal.core.gyro.recording.NAMED_UNITS`), are taken for them."""
    from optcal.core.gyro.recording import NAMED_UNITS

    return NAMED_UNITS.get(value.strip().lower(), value.strip())


def flags() -> dict[str, str]:
    """Parameter of optcal.core.recording (as its errors name it) -> the option that sets it: RawOptions' own list
    (``units`` is every command's --units, named as the parameter in the library's errors). Imported when an
    error is named: building the command line imports nothing of the recording package (numpy with it)."""
    from optcal.core.recording.options import RawOptions

    return {k: v for k, v in RawOptions.flags().items() if k not in ("units", "label_values")}

# what the library's errors name that is not a parameter of positions_from_raw: its choice of reader
READERS = {"raw": "--raw"}


def add_gravity_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("local gravity (default 1 g)")
    g.add_argument("--gravity-ms2", type=float, metavar="M_PER_S2", help="local gravity in m/s²")
    g.add_argument("--latitude", type=float, metavar="DEG", help="latitude for WGS84 normal gravity")
    g.add_argument("--height", type=float, metavar="M", help="ellipsoidal height, m (with --latitude; default 0)")


# the options that read a raw recording only (flag, argparse name): refused on a positions file
RAW_ONLY = (("--columns", "columns"), ("--time-unit", "time_unit"), ("--adc", "adc"), ("--labels", "labels"),
            ("--intervals", "intervals"), ("--min-static", "min_static"), ("--method", "method"))


def add_data_options(p: argparse.ArgumentParser, *, units_of_calibration: bool = False) -> None:
    d = p.add_argument_group("data")
    units_help = "output units of the data: g, m/s2, counts, volts, mg"
    units_help += (" (default: the calibration file's)" if units_of_calibration else
                   " (default: as the columns' names give them, e.g. ax(g) or Acc X [m/s^2]; else g)")
    d.add_argument("--units", help=units_help)
    d.add_argument("--raw", action="store_true", help="DATA is a raw recording (t, ax, ay, az per sample)")
    r = p.add_argument_group("raw recordings (with --raw; docs/design.md, 'Raw recordings')")
    r.add_argument("--topic", metavar="NAME[,GYRO]", help="a ROS bag's or PX4 ULog's IMU topic (default: its one IMU "
                   "topic); ACC,GYRO for an accelerometer and a gyroscope on topics of their own (docs/real_data.md)")
    r.add_argument("--columns", help="columns by name or 0-based index: t,ax,ay,az or ax,ay,az (with --rate), "
                   "t,ax,ay,az,temp, or role=column items")
    r.add_argument("--rate", type=float, metavar="HZ", help="sample rate when the recording has no time column")
    r.add_argument("--saturation", type=float, metavar="VALUE",
                   help="|output| at which a sample is saturated (default: the ADC's rails, see --adc, and "
                   "values an axis sticks to at its extremes)")
    r.add_argument("--adc", metavar="FORMAT", help="the counts' format, intB or uintB (int16, uint16, int12, ...); "
                   "its rails are saturation (default for counts: signed or unsigned 16, 24 or 32 bits from the data)")
    r.add_argument("--time-unit", choices=("s", "ms", "us", "ns"),
                   help="unit of the time column (default: from the median step, a rate of 1 Hz to 100 kHz)")
    r.add_argument("--intervals", metavar="FILE", help="static intervals by hand: JSON or CSV of start,end "
                   "sample indices (end exclusive), or imucal's section list")
    r.add_argument("--labels", metavar="COLUMN[=L1,L2,...]",
                   help="static intervals from a label column: runs of the listed labels (all if none)")
    r.add_argument("--method", choices=("segment", "variance"),
                   help="static-interval detector: change points and a rest test (default) or Tedaldi's variance "
                   "threshold (docs/segmentation.md)")
    r.add_argument("--min-static", type=float, metavar="S",
                   help="shortest pose, s (default: segmentation 0.5, variance detector 1)")
    r.add_argument("--window", type=float, metavar="S", help="segmentation: longest rest-test window, s (default "
                   "10); variance detector: its window, s (default 1)")
    r.add_argument("--init-s", type=float, metavar="S",
                   help="the variance detector's initial rest period, s (selects that detector; default: the first "
                   "2 s if they are at rest, else the noise floor of the quietest windows)")
    r.add_argument("--threshold-k", metavar="K|A:B", help="the variance detector's threshold multiplier(s) of the "
                   "initial-rest variance (selects that detector); a range is searched and the best fit kept "
                   "(2:10, as imu_tk)")
    add_gravity_options(p)


def gravity_from_args(args) -> float:
    lat, height = getattr(args, "latitude", None), getattr(args, "height", None)
    if height is not None and lat is None:  # even 0: a height given alone is a mistake, not a default
        raise InputError(f"--height {height:g} m without a latitude says nothing about local gravity; give "
                         "--latitude too, or leave --height out")
    return local_gravity_g(getattr(args, "gravity_ms2", None), lat, height)


def with_flags(message: str) -> str:
    """``message`` with each backquoted parameter of :func:`flags` replaced by its option."""
    table = {**flags(), **READERS}
    return re.sub(r"`(\w+)`", lambda m: table.get(m[1], m[0]), message)


@contextmanager
def flag_names():
    """Re-raise an InputError from the library with the options' names in place of its parameters'."""
    try:
        yield
    except InputError as exc:
        message = with_flags(str(exc))
        if message == str(exc):
            raise
        raise InputError(message) from exc


def parse_ks(spec) -> tuple[float, ...]:
    """``--threshold-k``: one multiplier ``4``, a range ``2:10`` (integer steps) or a list ``2,3,5``
    (:func:`optcal.core.recording.detection.parse_ks`, its errors naming the option)."""
    from optcal.core.recording.detection import parse_ks as multipliers

    with flag_names():
        return multipliers(spec)


def raw_options(args) -> RawOptions:
    """The raw-recording options (:class:`optcal.core.recording.options.RawOptions`) from the parsed command line."""
    from optcal.core.recording.options import RawOptions

    labels = getattr(args, "labels", None)
    column, values = (labels.split("=", 1) if labels is not None and "=" in labels else (labels, None))
    return RawOptions(
        columns=getattr(args, "columns", None), rate=getattr(args, "rate", None),
        units=getattr(args, "units", None), saturation=getattr(args, "saturation", None),
        adc=getattr(args, "adc", None), time_unit=getattr(args, "time_unit", None), topic=getattr(args, "topic", None),
        labels=column, label_values=None if values is None else values.split(","),
        intervals=getattr(args, "intervals", None) or None, method=getattr(args, "method", None),
        threshold_k=None if getattr(args, "threshold_k", None) is None else parse_ks(args.threshold_k),
        window_s=getattr(args, "window", None), min_static_s=getattr(args, "min_static", None),
        init_s=getattr(args, "init_s", None))


def load_raw_positions(args, path, gyro_of=None) -> PositionsData:
    """Positions from the raw recording ``path`` as the options ``args`` say, for the model calibrate's ``--model``
    or discover's ``--base`` names (default diag6); ``gyro_of(recording, file)`` gives the gyroscope's Recording at
    the same samples (``optcal imu``, ``calibrate --gyro``), whose stillness the detection also judges. With
    ``args.more_data``, several files of one sensor (a file per pose or face): each read, with its gyroscope, and
    joined in turn (:func:`optcal.core.recording.join.join_recordings`), so that no rest spans two files."""
    from optcal.app.workflows.recording import positions_from_raw_recording

    opts = raw_options(args)
    model = getattr(args, "model", None) or getattr(args, "base", None) or "diag6"
    g_local = gravity_from_args(args)
    paths = [path, *(getattr(args, "more_data", None) or [])]
    if len(paths) > 1 and getattr(args, "gyro", None) is not None:
        raise InputError("--gyro is one second file: with several DATA files, each file holds its gyroscope's "
                         "columns (named by its header, or by --gyro-columns)")
    with flag_names():
        recs = [opts.read(p) for p in paths]
        gyros = None if gyro_of is None else [gyro_of(r, p) for r, p in zip(recs, paths)]
        if len(paths) > 1:
            from optcal.core.recording.join import join_recordings

            recs = [join_recordings(recs)]
            gyros = None if gyros is None else [join_recordings(gyros)]
        return positions_from_raw_recording(recs[0], opts, gyro=None if gyros is None else gyros[0], model=model,
                                            g_local=g_local)


def load_positions(args, path, gyro_of=None) -> PositionsData:
    """Positions from a positions CSV or MAT file, or (``--raw``) from a raw recording via static-interval
    detection. A raw recording given as positions is named as such (and a positions file given with
    ``--raw`` by the reader): both by the one decision of :func:`optcal.core.recording.sniff.table_kind`, from the
    data, so that following one advice never meets the other. ``gyro_of``: as :func:`load_raw_positions`'s."""
    if getattr(args, "raw", False):
        return load_raw_positions(args, path, gyro_of)
    # a raw recording's options on a positions file would be dropped without a word (a user's --columns was)
    given = [f for f, a in RAW_ONLY if getattr(args, a, None) is not None]
    if given:
        raise InputError(f"{' and '.join(given[:2])} read{'s' if len(given) == 1 else ''} a raw recording: add --raw "
                         "(a positions file's columns are found by their names, ax, ay, az or acc_x, AccX, ...)")
    from optcal.core.recording.positions import read_positions_file

    with flag_names():
        return read_positions_file(path, units=args.units or "g")
