"""Small helpers shared by sub-commands: option parsing, JSON files, the parameter table."""

from __future__ import annotations

from pathlib import Path

from optcal.core.errors import InputError


def read_json_object(path: str, what: str) -> dict:
    import json  # here: a command that reads no JSON does not import it

    try:
        obj = json.loads(Path(path).read_text())
    except OSError as exc:
        raise InputError(f"cannot read {what} {path}: {exc.strerror}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{what} {path} is not valid JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(obj, dict):
        raise InputError(f"{what} {path} must be a JSON object")
    if isinstance(obj.get("parameters"), dict):  # a calibration file
        obj = obj["parameters"]
    return obj


def parse_options(items: list[str] | None) -> dict:
    """``KEY=VALUE`` pairs; values are parsed as JSON where they can be (numbers, true/false), else strings."""
    out = {}
    for item in items or []:
        if "=" not in item:
            raise InputError(f"--option {item!r} must be KEY=VALUE")
        k, v = item.split("=", 1)
        import json

        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out


def refuse_overwrite(path: str | None, force: bool) -> None:
    if path and Path(path).exists() and not force:
        raise InputError(f"{path} exists; choose another output path or pass --force to overwrite it")


def parameter_table(names, values, stderr=None, truth: dict | None = None, units: dict | None = None) -> str:
    """A fixed-width table: name, estimate, standard error, the unit of both (``units``: {name: unit}, from
    :meth:`optcal.core.model.Model.units`, docs/design.md, "Units and frames"), and the truth and error in SEs when
    given."""
    import numpy as np

    uw = max([4] + [len(units.get(n, "")) for n in names]) if units else 0
    head = f"{'parameter':<10} {'estimate':>16} {'std. error':>12}"
    if units:
        head += f" {'unit':<{uw}}"
    if truth:
        head += f" {'truth':>16} {'error/SE':>9}"
    lines = [head, "-" * len(head)]
    for i, n in enumerate(names):
        se = None if stderr is None else stderr[i]
        se_txt = "unobservable" if se is None or not np.isfinite(se) else f"{se:12.3e}"
        row = f"{n:<10} {values[i]:16.9g} {se_txt:>12}"
        if units:
            row += f" {units.get(n, ''):<{uw}}"
        if truth and n in truth:
            err = values[i] - truth[n]
            z = f"{err / se:9.2f}" if se is not None and np.isfinite(se) and se > 0 else f"{'':>9}"
            row += f" {truth[n]:16.9g} {z}"
        lines.append(row.rstrip())
    return "\n".join(lines)


def refuse_same_file(output: str | None, *inputs, option: str = "-o") -> None:
    """An output path that names one of the command's input files is refused: the input would be replaced by
    its own result."""
    from os.path import samefile

    if not output:
        return
    out = Path(output)
    for src in inputs:
        if not src:
            continue
        same = out.resolve() == Path(src).resolve()
        if not same and out.exists() and Path(src).exists():
            same = samefile(out, src)
        if same:
            raise InputError(f"{option} {output} is also an input of this command; write the result to another file")


def check_output_folder(path: str | None, option: str = "-o") -> None:
    """The folder an output is written to exists (checked before any work, so nothing is half done)."""
    if not path:
        return
    folder = Path(path).resolve().parent
    if not folder.is_dir():
        raise InputError(f"{option} {path}: the folder {folder} does not exist; create it or choose another path")


def check_seed(seed: int | None, option: str = "--seed") -> None:
    """Seeds of numpy's generators are non-negative integers."""
    if seed is not None and seed < 0:
        raise InputError(f"{option} {seed} is negative; give a seed of 0 or more")


def add_noise_from_options(p, dwell_help: str, reading: str) -> None:
    """``--noise-from`` and ``--dwell-s`` (calibrate, info): the Cramér-Rao bounds from a measured noise."""
    p.add_argument("--noise-from", metavar="RECORDING_OR_JSON",
                   help="white-noise density for the Cramér-Rao bounds, from the JSON of optcal noise --json or "
                   f"from a static recording ({reading}); the SD of a position mean is density/√dwell")
    p.add_argument("--dwell-s", type=float, metavar="S", help=dwell_help)


def noise_from_args(args, n_samples=None, rate: float | None = None) -> tuple[float, dict]:
    """σ of a position mean in g from ``--noise-from`` (N, g/√Hz) and the dwell T: N/√T (RMS over the
    positions when their dwells differ). T is ``--dwell-s``, else each position's ``n_samples`` over
    ``rate`` (the data's rate; the noise recording's when that is unknown). Also a summary for output."""
    import numpy as np

    from optcal.core.noise import load_white_noise

    reading = {"units": getattr(args, "units", None) or "g", "columns": getattr(args, "columns", None),
               "rate": getattr(args, "rate", None)}
    white = load_white_noise(args.noise_from, **reading)
    if args.dwell_s is not None:
        dwell, how = args.dwell_s, "--dwell-s"
    elif n_samples is not None:
        if rate is None or not np.isfinite(rate):
            rate, how = white.rate_hz, "the positions' n / the noise recording's rate"
        else:
            how = "the positions' n / the data's rate"
        if not np.isfinite(rate):
            raise InputError("the sample rate of the positions is unknown, so their dwell is; give --dwell-s")
        dwell = np.asarray(n_samples, float) / rate
    else:
        raise InputError("--noise-from needs the dwell of each position: give --dwell-s (the positions have no "
                         "n column)")
    sigma = white.sigma_of_mean_g(dwell)
    dwell_s = float(np.mean(dwell))
    summary = {"source": white.source, "density_ug_per_sqrt_hz": white.density_g * 1e6, "dwell_s": dwell_s,
               "dwell_from": how, "sigma_mean_ug": sigma * 1e6}
    return sigma, summary


def describe_noise(summary: dict) -> str:
    return (f"noise from {summary['source']}: white-noise density {summary['density_ug_per_sqrt_hz']:.4g} µg/√Hz, "
            f"dwell {summary['dwell_s']:.4g} s ({summary['dwell_from']}) → SD of a position mean "
            f"{summary['sigma_mean_ug']:.4g} µg")
