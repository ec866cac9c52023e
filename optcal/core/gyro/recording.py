"""A gyroscope's samples joined to the accelerometer's recording: the same times, the rests the
accelerometer's detection found, and the accelerometer's calibration turning its samples into specific
force (imu_tk's data come as two files sharing times; Tedaldi et al., ICRA 2014, §V)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from optcal.core.errors import InputError
from optcal.core.gyro.data import GAP_STEPS, GyroData
from optcal.core.model import Context, get_model
from optcal.core.recording.clock import CLOCK_TIME
from optcal.core.recording.robotlogs import TIME_TOLERANCE, at_times

# How the gyroscope's units are given to the reader, which only labels the samples with them
_READER_UNITS = {"counts": "counts", "deg/s": "volts", "rad/s": "volts", "volts": "volts"}

# The gyroscope's units as its columns' names give them (wx(deg/s), AsX(°/s), gyro_x [rad/s]), lower case
NAMED_UNITS = {**{u: "deg/s" for u in ("°/s", "deg/s", "dps", "degree/s", "degrees/s", "deg/sec", "°/sec", "º/s")},
               **{u: "rad/s" for u in ("rad/s", "rad/sec", "rads/s")}}


def join_times(t_acc: np.ndarray, t_gyro: np.ndarray) -> None:
    """Refuse two sample-time columns that are not the same times (within a tenth of a step)."""
    t_acc, t_gyro = np.asarray(t_acc, float), np.asarray(t_gyro, float)
    if len(t_acc) != len(t_gyro):
        raise InputError(f"the accelerometer has {len(t_acc)} samples and the gyroscope {len(t_gyro)}: the two "
                         "files must share their sample times; cut them to the same samples")
    step = float(np.median(np.diff(t_acc)))
    worst = float(np.max(np.abs(t_acc - t_gyro)))
    if worst > TIME_TOLERANCE * step:
        i = int(np.argmax(np.abs(t_acc - t_gyro)))
        raise InputError(f"the accelerometer's and gyroscope's times disagree by {worst:.3g} s at sample {i} "
                         f"(more than {TIME_TOLERANCE:g} of the {step:.3g} s step); resample them to common times")


def on_times_of(rec, acc):
    """The gyroscope's recording ``rec`` (a second file) at the accelerometer's times ``acc.t``: as it is when the
    two share their times, else interpolated linearly to them, as a ROS bag's gyroscope topic is
    (:func:`optcal.core.recording.robotlogs.at_times`). An accelerometer sample outside the gyroscope's span, or
    inside a gap of its samples (more than :data:`~optcal.core.gyro.data.GAP_STEPS` steps), has no gyroscope
    sample: NaN, which the rests' detection takes for motion and the gyroscope's fit leaves out with the motions
    holding it. ``reading["gyro_joined"]`` says how they were joined."""
    t, tg = np.asarray(acc.t, float), np.asarray(rec.t, float)
    if "t" not in acc.columns and "t" not in rec.columns and len(t) != len(tg):
        # times made from a rate start both files at 0: nothing says that they started together (a lab's pair of
        # 108,000 and 72,000 rows at 1,200 Hz was joined over its first 60 s without a word)
        raise InputError(f"the accelerometer's file has {len(t)} samples and the gyroscope's {len(tg)}, and neither "
                         "has a time column to align them by; give both files' times, or cut them to the same samples")
    if len(tg) < 2 or tg[-1] <= t[0] or tg[0] >= t[-1]:
        raise InputError(f"the gyroscope's times ({tg[0]:.6g}-{tg[-1]:.6g} s) and the accelerometer's "
                         f"({t[0]:.6g}-{t[-1]:.6g} s) do not overlap: give both files' times in one clock")
    # the rail flags go along, interpolated: a sample beside a saturated one is set aside too
    X, ok, same = at_times(t, tg, np.column_stack([rec.N, rec.saturated]), GAP_STEPS)
    if same:
        return rec
    if ok.mean() < 0.5:
        raise InputError(f"the gyroscope's samples cover {100 * ok.mean():.0f} % of the accelerometer's times: give "
                         "both files' times in one clock, or record both sensors throughout")
    N = np.where(ok[:, None], X[:, :3], np.nan)
    uncovered = int((~ok).sum())
    how = ("interpolated linearly to the accelerometer's times"
           + (f" ({uncovered} accelerometer sample(s) without a gyroscope sample: outside its span or in a gap of "
              "its samples)" if uncovered else ""))
    return replace(rec, t=t, N=N, rate=acc.rate, saturated=X[:, 3] > 0, temp=None, labels=None,
                   reading={**rec.reading, "gyro_joined": how, "gyro_uncovered": uncovered})


def _columns(spec, n: int) -> list[str] | None:
    if spec is None:
        return None
    parts = [c.strip() for c in spec.split(",")] if isinstance(spec, str) else [str(c).strip() for c in spec]
    if len(parts) != n or not all(parts):
        raise InputError(f"`gyro_columns` {','.join(parts) if not isinstance(spec, str) else spec!r} must name {n} "
                         "columns separated by commas")
    return parts


def units_from_names(names) -> str | None:
    """The gyroscope's units (deg/s or rad/s) its three columns' names give (:data:`NAMED_UNITS`), the same for
    all three; else None (:func:`optcal.core.recording.sniff.units_from_names` with the gyroscope's table)."""
    from optcal.core.recording.sniff import units_from_names as named_units

    return named_units(names, NAMED_UNITS)


def check_named_units(units: str, names, where) -> None:
    """Refuse a calibration whose gyroscope is in ``units`` for a recording whose gyroscope's columns' ``names``
    say other units (:func:`units_from_names`)."""
    _units(units, names, where, calibration=True)


def _units(units: str | None, names, where, calibration: bool = False) -> str:
    """``units`` checked against those the columns' ``names`` give (:func:`units_from_names`), or taken from
    them when None. ``calibration``: the units are a calibration's (the refusal says so)."""
    named = units_from_names(names) if names is not None and len(names) == 3 else None
    if units is None:
        if named is None:
            raise InputError("give the gyroscope's units with `gyro_units` counts, deg/s, rad/s or volts (the names of "
                             f"its columns in {where} give none)")
        return named
    if named is not None and units in NAMED_UNITS.values() and units != named:
        listed = ", ".join(map(str, names))
        raise InputError(f"{where}: the gyroscope's columns are in {named} ({listed}), the calibration's gyroscope "
                         f"in {units}; give its rates in {units}, or calibrate in {named}" if calibration else
                         f"`gyro_units` {units}, but the gyroscope's columns in {where} are in {named} ({listed}); "
                         f"give `gyro_units` {named}, or drop it")
    return units


def read_gyro(data, acc, *, gyro=None, gyro_columns=None, units: str | None, rate: float | None = None,
              time_unit: str | None = None, calibration: bool = False, interpolate: bool = False):
    """The gyroscope's samples as a :class:`~optcal.core.recording.Recording` (its ``N`` holds them), read from the
    file ``gyro`` (times and three rates; ``gyro_columns`` names the four, "t,gx,gy,gz", or its first four
    columns are taken) or from the accelerometer's file ``data``, whose recording ``acc`` is, in the columns
    ``gyro_columns`` ("gx,gy,gz" or a list) beside its time column, by default those its header names as the
    gyroscope's (gx, gyr_x, GyroX, ...: the columns ``optcal calibrate`` judges stillness on), also when the
    accelerometer's columns were named (``columns``) and the gyroscope's were not. ``units``: the
    gyroscope's (counts, deg/s, rad/s, volts); None takes them from its columns' names (``wx(deg/s)``), and
    given units that the names contradict are refused (``calibration``: the units are a calibration file's,
    which the refusal says). The units used are the recording's ``reading["gyro_units"]``. A ROS bag's or a
    ULog's gyroscope was read with its accelerometer: it is ``acc``'s (:func:`log_gyro`). ``interpolate``: a
    second file with its own times is taken at the accelerometer's (:func:`on_times_of`; a calibration's fit),
    else kept as it is (``apply`` writes the samples as they were; ``noise`` would see the interpolation's
    smoothing), and then refused by :func:`join_times` unless the times are the same."""
    rec = _read_gyro(data, acc, gyro=gyro, gyro_columns=gyro_columns, units=units, rate=rate, time_unit=time_unit,
                     calibration=calibration, interpolate=interpolate)
    return _with_piled_rails(rec)


def _with_piled_rails(rec):
    """``rec`` (the gyroscope's) with the samples at a rail its rates pile up at marked saturated too
    (:func:`optcal.core.recording.reading.piled_saturation`: a rail in converted units, held too briefly for a
    run), said in ``reading["gyro_piled"]``."""
    from optcal.core.recording.reading import piled_saturation

    N = np.asarray(rec.N, float)
    if rec.units == "counts" and np.all(N == np.round(N)):
        return rec  # whole counts: an ADC's rails are its format's (the reader finds them), no pile to look for
    piled, where = piled_saturation(N)
    if not where:
        return rec
    return replace(rec, saturated=np.asarray(rec.saturated, bool) | piled, reading={**rec.reading, "gyro_piled": where})


def _read_gyro(data, acc, *, gyro, gyro_columns, units, rate, time_unit, calibration, interpolate):
    """:func:`read_gyro` without its rails' pile-up check."""
    from optcal.core.recording.reading import read_recording

    if gyro is None and acc.reading.get("topic") is not None:
        rec = log_gyro(acc, units or "rad/s", gyro_columns)
        return replace(rec, reading={**rec.reading, "gyro_units": units or "rad/s"})
    even = bool(acc.reading.get("stamps_jitter_s"))  # the gyroscope's times as the accelerometer's were taken
    if gyro is not None:
        cols = _columns(gyro_columns, 4)
        spec = None if cols is None else f"t={cols[0]},ax={cols[1]},ay={cols[2]},az={cols[3]}"
        rec = read_recording(gyro, spec, rate, _READER_UNITS.get(units, "volts"), time_unit=time_unit, even=even)
        units = _units(units, [rec.columns[a] for a in ("ax", "ay", "az")], gyro, calibration)
        rec = on_times_of(rec, acc) if interpolate else rec
        return replace(rec, reading={**rec.reading, "gyro_units": units})
    cols = _columns(gyro_columns, 3)
    if cols is None and all(k in acc.columns for k in ("gx", "gy", "gz")):
        cols = [str(acc.columns[k]) for k in ("gx", "gy", "gz")]  # the header names them, as calibrate reads them
    if cols is None:  # the accelerometer's columns were named: the gyroscope the header names, if none is taken
        cols = _header_gyro_names(data, acc)
    if cols is None:
        raise InputError("name the gyroscope's columns in DATA with `gyro_columns` gx,gy,gz, or give them in a "
                         "second file with `gyro`")
    units = _units(units, cols, data, calibration)
    label = _READER_UNITS.get(units, "volts")
    time = acc.columns.get("t")
    if acc.reading.get("time_unit") == CLOCK_TIME:  # a time-of-day column: the accelerometer's seconds serve both
        rec = _rows_of(read_recording(data, f"ax={cols[0]},ay={cols[1]},az={cols[2]}", acc.rate, label, held=False),
                       acc)
        return replace(rec, t=acc.t, columns={**rec.columns, "t": time},
                       reading={**rec.reading, "time_unit": CLOCK_TIME, "gyro_units": units})
    spec = (f"t={time}," if time is not None else "") + f"ax={cols[0]},ay={cols[1]},az={cols[2]}"
    rec = _rows_of(read_recording(data, spec, rate, label, time_unit=time_unit, held=False, even=even), acc)
    return replace(rec, reading={**rec.reading, "gyro_units": units})


def _rows_of(rec, acc):
    """The rows of ``rec`` (every row of the file) that the accelerometer's recording ``acc`` of the same file
    kept: all of them, or, where the log repeats the accelerometer's samples (``reading["held_rows"]``), the rows
    at its samples' times."""
    if not acc.reading.get("held_rows"):
        return rec
    at = np.clip(np.searchsorted(rec.t, acc.t), 0, len(rec) - 1)
    if not np.array_equal(rec.t[at], acc.t):
        raise InputError(f"{acc.path}: the gyroscope's rows do not line up with the accelerometer's samples; give "
                         "the rate with `rate` or each sensor's time column")
    return replace(rec, t=acc.t, N=rec.N[at], rate=acc.rate, saturated=rec.saturated[at],
                   temp=None if rec.temp is None else rec.temp[at],
                   labels=None if rec.labels is None else rec.labels[at])


def _header_gyro_names(path, acc) -> list[str] | None:
    """The gyroscope's column names in ``path``'s header (all three axes, one column each, none of them among the
    accelerometer's columns), or None."""
    from optcal.core.recording.sniff import header_gyro, is_mat, sniff_layout

    if is_mat(Path(path)):
        return None
    lay = sniff_layout(Path(path))
    named = header_gyro(lay)
    used = {str(c) for c in acc.columns.values()}
    names = [lay.header[named[r]] for r in ("gx", "gy", "gz")] if named else None
    return names if names and not used & set(names) else None


def log_gyro(acc, units: str, gyro_columns=None):
    """The gyroscope of a ROS bag or a ULog, read with its accelerometer as the Recording ``acc`` (its ``W``), as
    a Recording of its own whose ``N`` holds the rates: what :func:`read_gyro` gives for a table's gyroscope
    columns (labelled as it labels rad/s, saturation found as for them). The log defines the units: rad/s."""
    from optcal.core.recording.reading import saturation_of
    from optcal.core.recording.robotlogs import check_gyro_units

    check_gyro_units(acc.path, units)
    if acc.W is None:
        raise InputError(f"{acc.path}: topic {acc.reading.get('topic')} has no gyroscope (angular_velocity); give "
                         "the gyroscope's topic too with `topic` ACC,GYRO")
    if gyro_columns is not None:
        names = [c.strip() for c in gyro_columns.split(",")] if isinstance(gyro_columns, str) else list(gyro_columns)
        if names != ["gx", "gy", "gz"]:
            raise InputError(f"`gyro_columns` {','.join(map(str, names))}: a log's gyroscope is its columns gx,gy,gz; "
                             "drop `gyro_columns`")
    label = _READER_UNITS[units]
    sat, _ = saturation_of(acc.W, label, None, None)
    return replace(acc, N=acc.W, units=label, saturated=sat, temp=None, W=None, gyro_saturated=None,
                   columns={"t": "t", "ax": "gx", "ay": "gy", "az": "gz"})


def gyro_data(t, W, N_acc, intervals, acc_model, x_acc, *, units: str,
              temp=None, rails: tuple[float, float] | None = None) -> GyroData:
    """The gyroscope's :class:`GyroData`: samples ``W`` (n, 3) at times ``t``, the accelerometer's raw
    samples ``N_acc`` calibrated by ``acc_model`` at ``x_acc`` into specific force (g), the rests
    ``intervals`` (r, 2) of its detection. A motion with a gyroscope sample at one of ``rails`` is left out of the
    motions, as ``optcal imu`` leaves it (:class:`GyroData`'s ``saturated``): its integrated rotation would be
    wrong."""
    model = get_model(acc_model)
    ctx = Context.from_columns(temp=temp if "temp" in model.needs else None, t=t if "t" in model.needs else None)
    F = model.inverse(np.asarray(x_acc, float)[None], np.asarray(N_acc, float), ctx)[0]
    W = np.asarray(W, float)
    saturated = None if rails is None else np.any((W <= rails[0]) | (W >= rails[1]), axis=1)
    return GyroData(t, W, F, intervals, units=units, saturated=saturated)
