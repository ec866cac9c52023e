"""The front door for Python users: ``optcal.calibrate``, ``optcal.apply``, ``optcal.read_recording`` and
``optcal.noise`` (docs/api.md has an example of each, and tests/test_api.py runs them).

This is the application layer over the library: :func:`calibrate` fits through :mod:`optcal.app.fit`, which
asks the solver registry by name; no core module imports this one. Heavy modules are imported inside the
functions, so that ``import optcal`` stays light (the package exposes these names lazily).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from optcal.core.errors import InputError

if TYPE_CHECKING:
    import numpy as np

    from optcal.core.calfile import CalibrationFile
    from optcal.core.calibration import Calibration
    from optcal.core.data import PositionsData
    from optcal.core.noise import NoiseReport
    from optcal.core.presets import Presets
    from optcal.core.recording import Recording


def _is_path(obj) -> bool:
    return isinstance(obj, str | os.PathLike)


def _positions(data, units: str | None, raw: bool, g_local: float, model, reading: dict) -> PositionsData:
    """``data`` as positions: a PositionsData as it is, an (n, 3) array of position means, or a file read as a
    positions CSV (docs/design.md, "Positions CSV") or, with ``raw``, a raw recording whose static intervals become the
    positions (design.md, "Raw recordings")."""
    import numpy as np

    from optcal.core.data import PositionsData, check_units

    if isinstance(data, PositionsData):
        if units is not None and units != data.units:
            raise InputError(f"the positions are in {data.units!r} but units={units!r}; drop units or convert them")
        if raw or reading:
            raise InputError("raw=True and the recording options apply to a file, not to a PositionsData")
        return data
    if _is_path(data):
        path = os.fspath(data)
        from optcal.core.recording.robotlogs import log_kind

        if not os.path.isfile(path) and log_kind(path) is None:  # a ROS 2 bag is a folder
            raise InputError(f"{path} does not exist or is not a file; give a positions CSV, or a raw recording "
                             "with raw=True")
        if raw:
            from optcal.app.workflows.recording import positions_from_raw

            return positions_from_raw(path, units=units, model=model, g_local=g_local, **reading)
        if reading:
            raise InputError(f"{', '.join(sorted(reading))} read a raw recording; pass raw=True with them")
        from optcal.core.recording.positions import read_positions_file

        return read_positions_file(path, units=units or "g")
    if raw or reading:
        raise InputError("raw=True and the recording options apply to a file path")
    try:
        N = np.asarray(data, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"data must be a PositionsData, an (n, 3) array of position means or a file path; "
                         f"got {type(data).__name__}") from None
    positions = PositionsData(N=N, units=units or "g")
    check_units(positions, positions.units)
    return positions


def _check_reading(function: str, reading: dict) -> None:
    """The recording options given as keyword arguments: :class:`optcal.core.recording.options.RawOptions`' names
    (``units`` is the functions' own argument)."""
    from optcal.core.recording.options import RawOptions

    RawOptions.of(function, **reading)


def calibrate(data, model=None, *, solver: str = "lm", units: str | None = None, raw: bool = False,
              g_local: float = 1.0, options: dict | None = None, reference: bool = False,
              presets: Presets | None = None, seed: int | None = 0, budget=None, noise_g: float | None = None,
              force_weak: bool = False, **reading) -> Calibration:
    """Fit ``model`` (a named model, a sum of terms, docs/design.md, "Named models and parameter order", or a Model)
    to ``data`` and return an :class:`optcal.core.calibration.Calibration` (parameters, standard errors, observability,
    goodness of fit).

    ``data``: a :class:`~optcal.core.data.PositionsData`; an (n, 3) array of position means in ``units``; or a path (str
    or pathlib.Path) to a positions CSV (design.md, "Positions CSV"), or, with ``raw=True``, to a raw recording whose
    static intervals are found as ``optcal calibrate --raw`` finds them (design.md, "Raw recordings"). ``units``: the
    outputs' units (g, m/s2, counts, volts, mg; default g). Keyword arguments for a raw recording, as
    :func:`optcal.app.workflows.recording.positions_from_raw` takes them: ``columns``, ``rate`` (Hz), ``saturation``,
    ``adc`` (the counts' format, e.g. "uint16"), ``time_unit`` (of the time column), ``topic`` (a ROS bag's or a PX4
    ULog's IMU topic, docs/real_data.md), ``labels`` (a label column) and ``label_values``, ``intervals`` (a file),
    ``method`` ("segment", the default, or "variance"), ``threshold_k`` ("2:10"), ``window_s``, ``min_static_s`` and
    ``init_s`` (s). ``g_local``: local gravity in g (``optcal.core.gravity.local_gravity_g`` converts m/s² or a
    latitude). The rest is :func:`optcal.app.fit.calibrate`'s: the registered solver and its options, turntable
    ``reference``, ``presets``, the solver's ``seed``, the evaluation ``budget`` and the noise SD of a position mean
    ``noise_g`` (g).

    The rules of ``optcal calibrate`` hold (docs/design.md, "Per-position residuals, outliers, the robust loss, what
    the data determine and weak fits"): a fit the data do not determine (too few
    positions for the model, an unobservable direction, fewer than 3 residual degrees of freedom, an exact
    fit, physically implausible parameters) raises :class:`~optcal.core.errors.InputError` with the CLI's line;
    ``model`` None (the default, nonlinear12) falls back to the richest of linear9 and diag6 that the data
    determine, with a note; ``force_weak=True`` returns the weak fit, its ``forced`` listing the reasons.
    """
    from optcal.app.fit import calibrate as fit

    _check_reading("calibrate", reading)

    positions = _positions_for(data, model, units, raw, g_local, reading)
    return fit(positions, model, solver=solver, options=options, g_local=g_local, reference=reference,
               presets=presets, seed=seed, budget=budget, noise_g=noise_g, force_weak=force_weak)


def _positions_for(data, model, units, raw: bool, g_local: float, reading: dict) -> PositionsData:
    """A raw recording's intervals are found for the model asked for; for the default, for nonlinear12, or, when
    the recording has too few intervals for it, for the next model of the fallback chain."""
    from optcal.core.determination import first_found

    return first_found(lambda name: _positions(data, units, raw, g_local, name, reading), model, raw)


GYRO_UNITS = ("counts", "deg/s", "rad/s", "volts")


def calibrate_imu(data, gyro=None, *, gyro_units: str | None = None, gyro_columns=None, gyro_scale: float | None = None,
                  gyro_bias: str = "rests", g_sensitivity: bool = False, model=None, solver: str = "lm",
                  units: str | None = None, g_local: float = 1.0, options: dict | None = None, seed: int = 0,
                  budget=None, force_weak: bool = False, **reading):
    """Calibrate an IMU's accelerometer and gyroscope from one raw recording of rests with rotations between
    them, as ``optcal imu`` does (docs/gyroscope.md): an :class:`optcal.app.imu.ImuCalibration` (``accelerometer``,
    ``gyroscope``, ``notes``; ``write(path)`` writes the IMU file that ``optcal apply`` and ``optcal export``
    read).

    ``data``: the path of the raw recording with the accelerometer's columns, read with ``units`` and the
    recording options of :func:`calibrate` (``columns``, ``rate``, ``method``, ``threshold_k``, ...).
    ``gyro``: the path of a second file with the gyroscope's samples (t, gx, gy, gz, or as ``gyro_columns``
    names them, as imu_tk's data come; at other times than the accelerometer's, interpolated to them);
    without it, ``gyro_columns`` names the three columns in ``data``. ``gyro_units``: counts, deg/s, rad/s or
    volts (None: as the gyroscope's columns' names give them, ``wx(deg/s)``; refused when they give none);
    ``gyro_scale``: nominal output units per rad/s (exact for deg/s and rad/s; otherwise searched for from the
    motions when None);
    ``gyro_bias``: ``rests`` (interpolated between them) or ``fit``; ``g_sensitivity`` (with ``gyro_bias``
    fit): fit G and keep it when the likelihood-ratio test finds it. ``model``, ``solver``, ``options``,
    ``g_local``, ``seed``, ``budget`` and ``force_weak`` as :func:`calibrate`'s, for both fits."""
    from optcal.app.imu import calibrate_imu as fit_imu
    from optcal.app.imu import check_imu_options
    from optcal.core.gyro.recording import read_gyro

    if gyro_units is not None and gyro_units not in GYRO_UNITS:
        raise InputError(f"gyro_units {gyro_units!r}: use one of {', '.join(GYRO_UNITS)}")
    _check_reading("calibrate_imu", reading)
    if not _is_path(data):
        raise InputError(f"calibrate_imu needs the path of a raw recording, got {type(data).__name__}")
    if gyro is not None and not _is_path(gyro):
        raise InputError(f"gyro must be the path of the gyroscope's file, got {type(gyro).__name__}")
    check_imu_options(gyro_scale=gyro_scale, gyro_bias=gyro_bias, g_sensitivity=g_sensitivity)
    from optcal.app.workflows.recording import positions_from_raw_recording
    from optcal.core.determination import first_found
    from optcal.core.recording.options import RawOptions

    # the recording is read once, and the gyroscope before the rests are found: their detection judges its
    # stillness too
    opts = RawOptions(units=units, **reading)
    acc = opts.read(os.fspath(data))
    rates = read_gyro(os.fspath(data), acc, gyro=None if gyro is None else os.fspath(gyro), gyro_columns=gyro_columns,
                      units=gyro_units, rate=opts.rate, time_unit=opts.time_unit, interpolate=True)
    positions = first_found(lambda name: positions_from_raw_recording(acc, opts, gyro=rates, model=name,
                                                                        g_local=g_local), model)
    return fit_imu(positions, rates, model=model, solver=solver, options=options, g_local=g_local, seed=seed,
                   budget=budget, gyro_units=rates.reading["gyro_units"], gyro_scale=gyro_scale, gyro_bias=gyro_bias,
                   g_sensitivity=g_sensitivity, force_weak=force_weak)


def apply_gyro(calibration, rates, force=None) -> np.ndarray:
    """Body rates in rad/s of raw gyroscope outputs ``rates`` (an (n, 3) array, or one sample of three, in the
    calibration's raw units). ``calibration``: what :func:`calibrate_imu` returns or the path of an IMU file
    (``optcal imu -o``). ``force``: the specific force (g) at the same samples (``optcal.apply`` of the
    accelerometer's), needed when the gyroscope was calibrated with g-sensitivity."""
    import numpy as np

    from optcal.app.imu import ImuCalibration
    from optcal.core.gyro.calfile import read_gyro_block

    if isinstance(calibration, ImuCalibration):
        gcal = read_gyro_block(calibration.to_dict(), "the IMU calibration")
    elif _is_path(calibration):
        from optcal.core.calfile import read_calibration

        # checked as optcal apply checks it (format, version, the accelerometer's part), then its gyroscope
        gcal = read_gyro_block(read_calibration(calibration).meta, os.fspath(calibration))
    else:
        raise InputError(f"calibration must be what optcal.calibrate_imu returns or an IMU file's path; got "
                         f"{type(calibration).__name__}")
    W = np.asarray(rates, dtype=float)
    one = W.shape == (3,)
    F = None if force is None else np.asarray(force, dtype=float).reshape(-1, 3)
    out = gcal.apply(W.reshape(1, 3) if one else W, F)
    return out[0] if one else out


def _calibration_file(calibration) -> CalibrationFile:
    from optcal.core.calfile import CalibrationFile
    from optcal.core.calibration import Calibration

    if isinstance(calibration, CalibrationFile):
        return calibration
    if isinstance(calibration, Calibration):
        # the file's record of the fit carries the context (T0, t0) that applying it needs (design.md, "Context:
        # temperature and time offsets")
        meta = calibration.file_record()
        return CalibrationFile(calibration.model, calibration.x, calibration.stderr, calibration.problem.g_local,
                               "g", calibration.problem.data.units, meta)
    if _is_path(calibration):
        return Calibration.read(calibration)
    raise InputError(f"calibration must be an optcal calibration (from optcal.calibrate), a CalibrationFile or "
                     f"a calibration-file path; got {type(calibration).__name__}")


def apply(calibration, samples, *, temp=None, t=None) -> np.ndarray:
    """Calibrated specific force in g (units of g0 = 9.80665 m/s²) of raw ``samples``: an (n, 3) array (or
    one sample of 3) in the calibration's output units. ``calibration``: what :func:`calibrate` returns, a
    :class:`~optcal.core.calfile.CalibrationFile` or the path of a calibration file (docs/design.md, "Calibration
    file"). The model is inverted exactly as ``optcal apply`` does (design.md, "The inverse: specific force from
    outputs"); models with temperature or drift terms need
    the samples' ``temp`` (°C) or ``t`` (s). A forced calibration (``force_weak``) is applied with a warning on
    the ``optcal`` logger naming its reasons."""
    import numpy as np

    cal = _calibration_file(calibration)
    if cal.forced:  # as optcal apply says it (docs/design.md, "Calibration file")
        import logging

        logging.getLogger("optcal").warning("applying a forced calibration (written with force_weak although the "
                                            "data did not determine it): %s", "; ".join(cal.forced))
    N = np.asarray(samples, dtype=float)
    one = N.shape == (3,)
    A = cal.apply(N.reshape(1, 3) if one else N, temp=temp, t=t)
    return A[0] if one else A


def read_recording(path, columns=None, rate: float | None = None, units: str = "g", *,
                   saturation: float | None = None, labels: str | None = None, need_time: bool = True,
                   adc: str | None = None, time_unit: str | None = None, topic: str | None = None) -> Recording:
    """A raw recording (docs/design.md, "Raw recordings") as a :class:`~optcal.core.recording.Recording`: samples ``N``
    (n, 3) in ``units``, time ``t`` (s), ``rate`` (Hz), optional ``temp`` (°C) and the ``saturated`` flags.
    ``columns``: "t,ax,ay,az", "ax,ay,az" (with ``rate``) or role=column items, names or 0-based indices
    (default: from the header); ``labels``: a column of section labels; ``need_time=False`` accepts a
    file with neither a time column nor a rate; ``adc``: the counts' format ("int16", "uint16", ...; default
    from the data); ``time_unit``: the time column's unit ("s", "ms", "us", "ns"; default from its step). A ROS
    bag (ROS 1 ``.bag``, a ROS 2 bag's folder or its ``.db3``/``.mcap``) or a PX4 ULog is read from its IMU
    messages, in m/s² (and the gyroscope's rad/s in ``W``) at their stamps; ``topic`` picks the IMU's topic
    ("NAME", or "ACC,GYRO"; docs/real_data.md)."""
    from optcal.core.recording import read_recording as read

    return read(path, columns, rate, units, saturation=saturation, labels=labels, need_time=need_time, adc=adc,
                time_unit=time_unit, topic=topic)


def noise(source, rate: float | None = None, *, units: str | None = None, columns=None, interval=None,
          scale: float | None = None, ci: float | None = None, tau_max_s: float | None = None,
          topic: str | None = None) -> NoiseReport:
    """The Allan-deviation noise analysis of a static stretch (docs/noise.md): white-noise density
    (g/√Hz), bias instability (g) and bias random walk (g/√s) per axis, with intervals, as a
    :class:`~optcal.core.noise.NoiseReport` (``table()``, ``to_dict()``, ``kalibr_yaml()``, ``figure()``).

    ``source``: a recording file (read as :func:`read_recording` reads it, with ``columns``, ``rate``,
    ``units`` and ``topic``; ``interval`` = (start, end) in seconds from its first sample), a
    :class:`~optcal.core.recording.Recording`, or an (n, 3) array of samples in ``units`` at ``rate`` Hz.
    ``scale``: output units per g for counts or volts (default: the mean output's magnitude); ``ci``: the
    confidence level (default 0.683); ``tau_max_s``: the longest averaging time (default a quarter of the
    stretch)."""
    from optcal.core.noise import analyse, noise_from_recording
    from optcal.core.recording import Recording

    kw = {"scale": scale, "tau_max_s": tau_max_s, **({} if ci is None else {"ci": ci})}
    if _is_path(source):
        return noise_from_recording(os.fspath(source), columns=columns, rate=rate, units=units,
                                    interval=interval, topic=topic, **kw)
    if interval is not None or columns is not None or topic is not None:
        raise InputError("interval, columns and topic apply to a recording file; slice the samples instead")
    if isinstance(source, Recording):
        if units is not None and units != source.units:
            raise InputError(f"the recording is in {source.units!r} but units={units!r}; drop units")
        if rate is not None and source.rate == source.rate and abs(rate / source.rate - 1) > 1e-9:
            raise InputError(f"the recording's rate is {source.rate:g} Hz but rate={rate:g}; drop rate")
        return analyse(source.N, source.rate if rate is None else rate, units=source.units, source=source.path, **kw)
    if rate is None:
        raise InputError("the samples' rate is needed: noise(samples, rate=HZ)")
    return analyse(source, rate, units=units or "g", **kw)
