"""optcal calibrate: fit a model to a positions CSV (or a raw recording with --raw)."""

from __future__ import annotations

import argparse
import json

from optcal.app.commands._common import (
    add_noise_from_options,
    check_output_folder,
    check_seed,
    describe_noise,
    noise_from_args,
    parameter_table,
    parse_options,
    refuse_overwrite,
    refuse_same_file,
)
from optcal.app.commands._dataopts import add_data_options, flag_names, gravity_from_args, load_positions
from optcal.core.errors import InputError

HELP = "calibrate an accelerometer from static positions (default model nonlinear12, or smaller if the data ask)"


class NamedModel(argparse.Action):
    """``--model`` as given: sets the model and notes that the user named one. Only the default model falls back
    to a smaller one when the positions do not determine it (docs/design.md, "Per-position residuals, outliers, the
    robust loss, what the data determine and weak fits"); a named one is refused."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        namespace.model_named = True


def add_arguments(p):
    p.add_argument("data", metavar="DATA", help="positions CSV (or a raw recording with --raw)")
    p.add_argument("more_data", nargs="*", metavar="MORE", help="with --raw: more recordings of the same sensor, "
                   "at the same rate (a file per pose or per face), joined in turn to DATA: no rest spans two files")
    p.add_argument("--model", default="nonlinear12", action=NamedModel,
                   help="model name or sum of terms (default nonlinear12; when the positions do not determine it, "
                   "the richest of linear9 and diag6 that they do, said in a note)")
    p.set_defaults(model_named=False)
    p.add_argument("--solver", default="lm", help="registered solver, e.g. scipy-lm, bsas, staged:bsas (default lm)")
    p.add_argument("--option", action="append", metavar="KEY=VALUE", help="solver option (repeatable)")
    p.add_argument("--seed", type=int, default=0, help="seed of the solver's random generator")
    p.add_argument("--budget", type=int, help="evaluation budget (default: the solver's)")
    p.add_argument("--presets", help="presets JSON ({name: value} or {values, halfwidth}) for the search centre")
    p.add_argument("--reference", action="store_true", help="turntable data: fit N to the known ref_x, ref_y, ref_z")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("-o", "--output", metavar="CALIBRATION.json", help="write the calibration file")
    p.add_argument("--force", action="store_true", help="overwrite an existing calibration file or figure")
    p.add_argument("--force-weak", action="store_true", help="write a fit the data do not determine (too few "
                   "positions to check it, fewer than 3 residual degrees of freedom, an exact fit, implausible "
                   "parameters) instead of refusing it; the file records that it was forced and why (fewer positions "
                   "than the model's parameters have no one fit to force: still refused)")
    p.add_argument("--plot", metavar="FILE.png", help="the residual per position with its noise band and the "
                   "outliers (with --raw: the recording with its intervals and residuals); the suffix names the "
                   "format: .png, .pdf, .svg, ...")
    p.add_argument("--gyro", metavar="GYRO_FILE", help="with --raw: a second file with the gyroscope's samples "
                   "(t, gx, gy, gz; at its own times, interpolated to DATA's), whose stillness the rests are judged on "
                   "too, as optcal imu judges them (the fit is the accelerometer's)")
    p.add_argument("--gyro-columns", metavar="SPEC", help="with --raw: the gyroscope's columns by name or 0-based "
                   "index, gx,gy,gz in DATA (default: those its header names, e.g. gx or gyr_x), or t,gx,gy,gz in "
                   "--gyro (default: its first four), as optcal imu takes them")
    add_noise_from_options(p, "dwell per position for --noise-from, s (default: each position's n over the "
                           "sample rate: a raw DATA's, else --rate, else the noise recording's)",
                           "read with --units, --columns and --rate, as a raw DATA")
    add_data_options(p)


def _gyro_of(args):
    """With ``--gyro`` or ``--gyro-columns``: the gyroscope's samples at the recording's times, for the rests'
    stillness (its units do not matter there: the detection is units-free), else None."""
    if getattr(args, "gyro", None) is None and getattr(args, "gyro_columns", None) is None:
        return None
    from optcal.core.gyro.recording import read_gyro

    return lambda rec, path: read_gyro(path, rec, gyro=args.gyro, gyro_columns=args.gyro_columns, units="volts",
                                       rate=args.rate, time_unit=args.time_unit, interpolate=True)


def _default_positions(args):
    """Positions for the default model: a raw recording's intervals found for the richest model of the fallback
    chain that has enough of them (:func:`optcal.core.determination.first_found`)."""
    from optcal.core.determination import first_found

    def find(name):
        args.model = name
        return load_positions(args, args.data, _gyro_of(args))

    return first_found(find, None, getattr(args, "raw", False))


def run(args) -> int:
    from optcal.app.fit import calibrate
    from optcal.core.presets import load_presets

    check_seed(args.seed)
    if args.dwell_s is not None and not args.noise_from:
        raise InputError("--dwell-s sets the dwell for --noise-from; give --noise-from too, or leave it out")
    if args.budget is not None and args.budget < 1:
        raise InputError(f"--budget {args.budget} must be a number of evaluations of 1 or more")
    if args.more_data and not args.raw:
        raise InputError(f"{len(args.more_data) + 1} files are read as one raw recording: give --raw (a positions "
                         "file is one file)")
    if (args.gyro is not None or args.gyro_columns is not None) and not args.raw:
        flag = "--gyro" if args.gyro is not None else "--gyro-columns"
        raise InputError(f"{flag} judges the rests of a raw recording on its gyroscope too: give --raw")
    inputs = (args.data, *args.more_data, args.presets, args.noise_from, args.gyro)
    refuse_same_file(args.output, *inputs)
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    if args.plot:  # checked before anything is fitted or written
        from optcal.core.plots import check_figure_path

        refuse_same_file(args.plot, *inputs, args.output, option="--plot")
        refuse_overwrite(args.plot, args.force)
        check_figure_path(args.plot)
    g_local = gravity_from_args(args)
    named = args.model_named
    data = load_positions(args, args.data, _gyro_of(args)) if named else _default_positions(args)
    presets = load_presets(args.presets) if args.presets else None
    detection = data.extra.get("detection") if isinstance(data.extra, dict) else None
    noise_g, noise = None, None
    if args.noise_from:
        rate = detection.recording.rate if detection is not None else args.rate
        with flag_names():  # a noise recording is read with --columns and --rate
            noise_g, noise = noise_from_args(args, data.n_samples, rate)
    cal = calibrate(data, args.model if named else None, solver=args.solver, options=parse_options(args.option),
                    g_local=g_local, reference=args.reference, presets=presets, seed=args.seed, budget=args.budget,
                    noise_g=noise_g, force_weak=args.force_weak)
    figure = None
    if args.plot and detection is not None:
        from optcal.core.plots.recording import recording_figure

        # the intervals of the positions fitted (the poses' recheck may have trimmed or dropped some): a bar each
        fitted = cal.problem.data.extra.get("detection") if isinstance(cal.problem.data.extra, dict) else None
        figure = recording_figure(detection.recording, fitted or detection, cal.problem.residuals_full(cal.x)[0])
    elif args.plot:
        from optcal.core.plots.fit import fit_figure

        figure = fit_figure(cal)
    if args.output:
        cal.write(args.output, units_out=args.units, source=str(args.data), overwrite=args.force)
    if figure is not None:
        from optcal.core.plots import save_figure

        save_figure(figure, args.plot)
    if args.json:
        units = cal.model.units(data.units)  # beside "parameters", in the same order (docs/design.md, "Units and
                                             # frames")
        extra = {"noise_from": noise} if noise else {}
        floor = data.extra.get("noise_floor") if isinstance(data.extra, dict) else None
        if floor is not None:
            extra["noise_floor"] = floor.to_dict()
        if detection is not None:
            from optcal.core.recording.report import detection_summary

            extra["recording"] = detection_summary(detection)
        print(json.dumps({**cal.to_dict(), "units": units, "output_units": data.units, **extra}, indent=2))
        return 0
    if detection is not None:
        from optcal.core.recording.report import describe_detection

        print(describe_detection(detection))
    used = len(cal.problem.data)  # the poses' recheck may have dropped some (a note names each)
    dropped = f" ({len(data) - used} of the {len(data)} dropped: see the notes)" if used != len(data) else ""
    print(f"model {cal.model.name}, {used} positions{dropped}, outputs in {data.units}, "
          f"g_local = {cal.problem.g_local:.9f} g, solver {cal.solver}")
    print(f"residual RMS {cal.fit.rms_g * 1e6:.3f} µg, cost {cal.fit.cost:.6e}, "
          f"{cal.result.nfev} evaluations, {cal.result.runtime_s * 1e3:.1f} ms ({cal.result.message})")
    print(cal.fit.describe())
    floor = data.extra.get("noise_floor") if isinstance(data.extra, dict) else None
    if floor is not None and data.sem is not None:
        print(floor.describe())
    print("observability: " + cal.observability.describe())
    if noise:
        print(describe_noise(noise))
    for note in cal.notes:
        print(f"note: {note}")
    if any(row["outlier"] for row in cal.positions):
        print(cal.residual_table())
    print(parameter_table(cal.model.names, cal.x, cal.stderr, units=cal.model.units(data.units)))
    for written in (args.output, args.plot):
        if written:
            print(f"wrote {written}")
    return 0
