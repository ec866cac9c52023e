"""optcal apply: turn a raw recording into calibrated specific force with a calibration file."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError
from ..gravity import G0
from ._common import check_output_folder, refuse_overwrite, refuse_same_file
from ._dataopts import add_data_options, flag_names, gravity_from_args

if TYPE_CHECKING:
    import numpy as np

HELP = "apply a calibration file to a raw recording: raw outputs -> specific force in g or m/s²"
OUTPUT_UNITS = {"g": 1.0, "m/s2": G0}


def add_arguments(p):
    p.add_argument("calibration", metavar="CALIBRATION.json", help="calibration file (optcal calibrate -o)")
    p.add_argument("data", metavar="RAW", help="raw recording (CSV or whitespace-separated; see --columns)")
    p.add_argument("-o", "--output", required=True, metavar="CALIBRATED.csv", help="output CSV")
    p.add_argument("--output-units", choices=tuple(OUTPUT_UNITS), default="g",
                   help="units of the calibrated specific force (default g = 9.80665 m/s²)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    add_data_options(p, units_default=None)


def write_csv(path: Path, columns: dict[str, np.ndarray], fmt: dict[str, str]) -> None:
    """A header and one row per sample, written in blocks (no Python loop over values)."""
    import numpy as np

    names = list(columns)
    M = np.column_stack([np.asarray(columns[c], float) for c in names])
    row = ",".join(fmt[c] for c in names)
    try:
        with open(path, "w") as fh:
            fh.write(",".join(names) + "\n")
            np.savetxt(fh, M, fmt=row.split(","), delimiter=",")
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None


# Options of add_data_options that only the static-interval detector reads: apply converts every sample.
DETECTOR_OPTIONS = {"raw": ("--raw", False), "intervals": ("--intervals", None), "labels": ("--labels", None),
                    "init_s": ("--init-s", None), "threshold_k": ("--threshold-k", None),
                    "method": ("--method", None), "window": ("--window", None), "min_static": ("--min-static", None)}
# The median magnitude of the raw outputs against the calibration's at rest (|K|·g_local): beyond this factor
# either way the data are not in the calibration's units (docs/design.md §9.3).
MAGNITUDE_FACTOR = 4.0


def check_magnitude(cal, N, path) -> None:
    """Refuse raw outputs whose typical magnitude is not what the calibration's sensor gives at 1 g, naming
    the units the data look like (a calibration fitted in counts applied to data in g, ...)."""
    import numpy as np

    from ..data import guess_units

    with np.errstate(over="ignore", invalid="ignore"):
        med = float(np.median(np.linalg.norm(N, axis=1)))
    K = cal.x[cal.model.groups()["scale"]]
    expect = float(np.mean(np.abs(K))) * cal.g_local
    if not (np.isfinite(med) and med > 0 and 1 / MAGNITUDE_FACTOR <= med / expect <= MAGNITUDE_FACTOR):
        looks = guess_units(med)
        hint = f", which looks like {looks}" if looks and looks != cal.units_out else ""
        raise InputError(f"the raw outputs of {path} have a median magnitude of {med:.4g}{hint}, but the calibration "
                         f"was fitted to outputs in {cal.units_out!r}, which read about {expect:.4g} at rest; apply "
                         f"a calibration fitted in the data's units")


def run(args) -> int:
    import numpy as np

    from ..calfile import read_calibration
    from ..recording.reading import read_recording

    given = [flag for key, (flag, default) in DETECTOR_OPTIONS.items() if getattr(args, key, default) != default]
    if given:
        raise InputError(f"{', '.join(given)} select static intervals, which apply does not: it converts every "
                         "sample of the recording; drop them")
    refuse_same_file(args.output, args.calibration, args.data)
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    g = gravity_from_args(args)
    cal = read_calibration(args.calibration)
    if args.units is not None and args.units != cal.units_out:
        raise InputError(
            f"the data are declared in {args.units!r} but {args.calibration} was fitted to outputs in "
            f"{cal.units_out!r}; convert the data or drop --units"
        )
    try:
        with flag_names():
            rec = read_recording(args.data, args.columns, args.rate, cal.units_out, saturation=args.saturation,
                                 need_time="t" in cal.model.needs, adc=args.adc, time_unit=args.time_unit)
    except InputError as exc:
        if "looks like" not in str(exc) or args.units is not None:
            raise
        # the data were read in the calibration's units, which the user did not choose: say so
        raise InputError(f"{exc} (apply reads the data in {cal.units_out!r}, the units {args.calibration} was "
                         "fitted to: with data in other units, apply a calibration fitted in those)") from None
    check_magnitude(cal, rec.N, args.data)
    has_t = "t" in rec.columns
    A = cal.apply(rec.N, temp=rec.temp, t=rec.t if has_t else None)
    scale = OUTPUT_UNITS[args.output_units]
    cols: dict[str, np.ndarray] = {}
    if has_t or np.isfinite(rec.rate):
        cols["t"] = rec.t
    for j, c in enumerate(("ax", "ay", "az")):
        cols[c] = A[:, j] * scale
    if rec.temp is not None:
        cols["temp"] = rec.temp
    if rec.saturated.any():
        cols["saturated"] = rec.saturated.astype(float)
    fmt = {c: "%.10g" for c in cols}
    fmt["saturated"] = "%d"
    write_csv(Path(args.output), cols, fmt)
    norm = np.linalg.norm(A, axis=1)
    print(f"applied {args.calibration} (model {cal.model.name}, outputs in {cal.units_out}) to {len(rec)} samples "
          f"of {args.data}; wrote {args.output} (ax, ay, az in {args.output_units})")
    print(f"median |A| = {np.median(norm):.6f} g (calibration's local gravity {cal.g_local:.6f} g)")
    if cal.forced:
        print(f"note: applying a forced calibration (written with --force-weak although the data did not determine "
              f"it): {'; '.join(cal.forced)}")
    if rec.saturated.any():
        print(f"note: {int(rec.saturated.sum())} saturated sample(s) are flagged in column 'saturated'")
    gave_gravity = getattr(args, "gravity_ms2", None) is not None or args.latitude is not None
    if gave_gravity and abs(g - cal.g_local) > 1e-6:
        print(f"note: the local gravity given ({g:.6f} g) differs from the calibration's ({cal.g_local:.6f} g); "
              "the output is specific force and does not depend on it")
    return 0
