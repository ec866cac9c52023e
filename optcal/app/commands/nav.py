"""optcal nav: the position error a calibration causes in a static navigation run (2020 paper §5.2, Eq. 23)."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from optcal.core.errors import InputError

if TYPE_CHECKING:
    import numpy as np

    from optcal.core.model import Model

HELP = "position error of a 5-hour static navigation run with a calibration, against the truth"


@functools.cache
def _owners() -> dict[str, str]:
    """{parameter name: the term that owns it}. A name shared by `misalignment` and `misalignment6` goes to
    the 3-angle gauge unless a six-angle-only name is present (docs/design.md, "Terms and parameters"); every other
    name has exactly one owning term."""
    from optcal.core.model import TERMS

    owner: dict[str, str] = {}
    for t in TERMS.values():
        for p in t.params:
            owner.setdefault(p, t.name)
    return owner


def add_arguments(p):
    p.add_argument("calibration", metavar="CALIBRATION.json", help="calibration file (optcal calibrate -o)")
    p.add_argument("--truth", required=True, metavar="TRUTH.json",
                   help="the true parameters: a calibration file or a JSON object {name: value}")
    p.add_argument("--hours", type=float, default=5.0, help="length of the run, h (default 5)")
    p.add_argument("--latitude", type=float, default=45.0, metavar="DEG", help="latitude, deg (default 45)")
    p.add_argument("--height", type=float, default=0.0, metavar="M", help="ellipsoidal height, m (default 0)")
    p.add_argument("--attitude", default="0,0,0", metavar="ROLL,PITCH,YAW",
                   help="fixed attitude in deg, FRD body against NED (default 0,0,0: x north, z down); "
                   "write a negative first angle as --attitude=-10,0,0")
    p.add_argument("--gyro-bias-dph", default="0,0,0", metavar="X,Y,Z", help="constant gyro bias, deg/h, body frame")
    p.add_argument("--self-align", action="store_true",
                   help="run a static self-alignment first (default: the initial attitude is known)")
    p.add_argument("--plot", metavar="FILE.png", help="plot latitude, longitude and position error over time")
    p.add_argument("--force", action="store_true", help="overwrite an existing --plot file")
    p.add_argument("--json", action="store_true",
                   help="print {max_error_nmi, mean_error_nmi, hours, latitude_deg} as JSON")


def _triple(text: str, option: str) -> tuple[float, float, float]:
    parts = str(text).split(",")
    try:
        vals = tuple(float(v) for v in parts)
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
        raise InputError(f"{option} {text!r} must be three numbers separated by commas, e.g. 0,0,90")
    return vals


def _load_truth(path: str) -> tuple[dict[str, float], tuple[str, ...], str | None]:
    """(parameters, terms, output units) of TRUTH.json: a calibration file or a plain {name: value}."""
    from optcal.core.calfile import FORMAT, read_calibration

    try:
        obj = json.loads(Path(path).read_text())
    except OSError as exc:
        raise InputError(f"cannot read truth {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"truth {path} is not valid JSON ({exc})") from None
    if not isinstance(obj, dict):
        raise InputError(f"truth {path} must be a JSON object {{name: value}} or a calibration file")
    if not obj:
        raise InputError(f"truth {path} is empty; give the true parameters {{name: value}} (at least K_x, K_y, K_z) "
                         "or a calibration file")
    if obj.get("format") == FORMAT:
        cal = read_calibration(path)
        return cal.parameters, cal.model.terms, cal.units_out
    unknown = sorted(k for k in obj if k not in _owners())
    if unknown:
        raise InputError(f"truth {path} has unknown parameter name(s) {', '.join(unknown)}; "
                         f"known names are those of docs/design.md, 'Terms and parameters', e.g. K_x, b_x, S_yz, K2_x")
    values = {}
    for k, v in obj.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise InputError(f"truth {path}: {k} = {v!r} is not a finite number")
        values[k] = float(v)
    return values, _terms_of(values), None


# The truth's scale factors against the calibration's: beyond this factor either way they are in other units.
SCALE_FACTOR_RATIO = 4.0


def _check_plain_truth_units(path, truth: dict, K_true, cal) -> None:
    """A plain {name: value} truth states no units: its scale factors (1 where it has none) must be of the
    calibration's size, else the two are in different output units (docs/design.md, "Calibration file")."""
    import numpy as np

    from optcal.core.data import guess_units

    k_t, k_c = float(np.mean(np.abs(K_true))), float(np.mean(np.abs(cal.x[cal.model.groups()["scale"]])))
    if 1 / SCALE_FACTOR_RATIO <= k_t / k_c <= SCALE_FACTOR_RATIO:
        return
    looks = guess_units(k_t)
    given = "" if any(n.startswith("K_") for n in truth) else " (it gives none, so 1)"
    like = f", which looks like outputs in {looks}" if looks else ""
    raise InputError(f"truth {path}'s scale factors are about {k_t:.4g}{given}{like}, but the calibration's are about "
                     f"{k_c:.4g} (outputs in {cal.units_out}); give the truth in {cal.units_out}, or as a calibration "
                     "file that states its units")


def _terms_of(names) -> tuple[str, ...]:
    owner = _owners()
    six = any(owner[n] == "misalignment6" for n in names)
    terms = {("misalignment6" if six and owner[n] == "misalignment" else owner[n]) for n in names}
    return tuple(terms)


def union_model(*term_sets) -> Model:
    """The model holding every parameter of the given term sets (3-angle and 6-angle misalignment merge
    into the six angles, which contain the three)."""
    from optcal.core.model import get_model

    terms = {"scale"}.union(*term_sets)
    if {"misalignment", "misalignment6"} <= terms:
        terms.discard("misalignment")
    return get_model("+".join(sorted(terms)))


def vectors(model: Model, truth: dict[str, float], estimate: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """Truth and estimate on ``model``: missing parameters are 0, a missing scale factor is the truth's
    (or 1 if neither has it)."""
    import numpy as np

    x_true = model.from_dict(truth)
    base = np.zeros(model.n_params)
    scale = model.groups()["scale"]
    base[scale] = x_true[scale]
    x_est = model.from_dict(estimate, base=base)
    return x_true, x_est


def _write_plot(args, draw) -> None:
    """``draw(fh)`` saves the figure to the file handle ``fh``: a temporary file beside --plot, renamed over it
    when complete (optcal.core.atomicfile: an interrupted write leaves the old file), in the format --plot's suffix
    names (matplotlib takes a file handle's format from ``savefig.format``)."""
    import matplotlib

    from optcal.core.atomicfile import atomic_write

    with atomic_write(args.plot, overwrite=args.force, binary=True,
                      exists="{path} exists; choose another --plot path or pass --force to overwrite it") as fh:
        try:
            with matplotlib.rc_context({"savefig.format": Path(args.plot).suffix.lower().lstrip(".")}):
                draw(fh)
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot write the plot {args.plot}: {getattr(exc, 'strerror', None) or exc}") from None


def run(args) -> int:
    import numpy as np

    from optcal.core.calfile import read_calibration
    from optcal.core.nav import navigation_error, plot_navigation

    attitude = _triple(args.attitude, "--attitude")
    gyro = _triple(args.gyro_bias_dph, "--gyro-bias-dph")
    if args.plot:  # checked before anything is computed
        from optcal.core.plots import check_figure_path

        if not Path(args.plot).resolve().parent.is_dir():
            raise InputError(f"cannot write the plot {args.plot}: the folder {Path(args.plot).resolve().parent} does "
                             "not exist; create it or choose another path")
        if Path(args.plot).resolve() in (Path(args.calibration).resolve(), Path(args.truth).resolve()):
            raise InputError(f"--plot {args.plot} is also an input of this command; write the figure elsewhere")
        if Path(args.plot).exists() and not args.force:
            raise InputError(f"{args.plot} exists; choose another --plot path or pass --force to overwrite it")
        check_figure_path(args.plot)
    cal = read_calibration(args.calibration)
    truth, truth_terms, truth_units = _load_truth(args.truth)
    if truth_units is not None and truth_units != cal.units_out:
        raise InputError(f"truth is in output units {truth_units!r} but the calibration in {cal.units_out!r}; "
                         "compare calibrations of the same output units")
    model = union_model(cal.model.terms, truth_terms)
    x_true, x_est = vectors(model, truth, cal.parameters)
    if np.any(x_true[model.groups()["scale"]] == 0):
        raise InputError(f"truth {args.truth} has a zero scale factor; give K_x, K_y, K_z")
    if truth_units is None:
        _check_plain_truth_units(args.truth, truth, x_true[model.groups()["scale"]], cal)
    res = navigation_error(model, x_true, x_est, hours=args.hours, latitude_deg=args.latitude,
                           height_m=args.height, attitude_deg=attitude, gyro_bias_dph=gyro,
                           self_alignment=args.self_align)
    if args.plot:
        label = "self-aligned" if args.self_align else "known attitude"
        _write_plot(args, lambda fh: plot_navigation(
            {label: res}, fh, title=f"{Path(args.calibration).name} vs truth, {args.hours:g} h at {args.latitude:g}°"))
    if args.json:
        print(json.dumps(res.to_dict()))
        return 0
    print(f"static navigation, {args.hours:g} h at latitude {args.latitude:g}°, height {args.height:g} m, "
          f"attitude {','.join(f'{a:g}' for a in attitude)} deg, "
          f"{'self-aligned' if args.self_align else 'known initial attitude'}")
    print(f"model {model.name}: calibration {args.calibration} against truth {args.truth}")
    print(f"position error: max {res.max_error_nmi:.4f} nmi, mean {res.mean_error_nmi:.4f} nmi")
    if args.plot:
        print(f"wrote {args.plot}")
    return 0
