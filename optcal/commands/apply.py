"""optcal apply: turn a raw recording into calibrated specific force with a calibration file."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError
from ..gravity import G0
from ._common import refuse_overwrite
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


def run(args) -> int:
    import numpy as np

    from ..calfile import read_calibration
    from ..recording.reading import read_recording

    refuse_overwrite(args.output, args.force)
    cal = read_calibration(args.calibration)
    if args.units is not None and args.units != cal.units_out:
        raise InputError(
            f"the data are declared in {args.units!r} but {args.calibration} was fitted to outputs in "
            f"{cal.units_out!r}; convert the data or drop --units"
        )
    g = gravity_from_args(args) if (args.gravity is not None or args.latitude is not None) else None
    with flag_names():
        rec = read_recording(args.data, args.columns, args.rate, cal.units_out, saturation=args.saturation,
                             need_time="t" in cal.model.needs)
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
    if rec.saturated.any():
        print(f"note: {int(rec.saturated.sum())} saturated sample(s) are flagged in column 'saturated'")
    if g is not None and abs(g - cal.g_local) > 1e-6:
        print(f"note: the local gravity given ({g:.6f} g) differs from the calibration's ({cal.g_local:.6f} g); "
              "the output is specific force and does not depend on it")
    return 0
