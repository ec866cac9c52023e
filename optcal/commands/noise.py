"""optcal noise: white-noise density, bias instability and bias random walk of a static recording, from
its overlapping Allan deviation (the method and its references: optcal/noise/; docs/noise.md). The figure is
optcal.plots.noise's."""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..errors import InputError
from ._common import refuse_overwrite, refuse_same_file

HELP = ("noise of a static recording from its Allan deviation: white-noise density, bias instability, "
        "bias random walk; Kalibr's imu.yaml")


def add_arguments(p):
    p.add_argument("recording", metavar="RECORDING", help="raw recording of the sensor at rest (t, ax, ay, az per "
                   "sample, or ax, ay, az with --rate; as optcal calibrate --raw reads it)")
    p.add_argument("--interval", metavar="START:END",
                   help="the static stretch, seconds from the first sample (either may be empty; default the "
                   "whole file)")
    d = p.add_argument_group("reading the recording (as optcal calibrate --raw)")
    d.add_argument("--units", default="g", help="output units: g, m/s2, counts, volts, mg (default g)")
    d.add_argument("--columns", help="columns by name or 0-based index: t,ax,ay,az or ax,ay,az (with --rate), "
                   "or role=column items (default: from the header)")
    d.add_argument("--rate", type=float, metavar="HZ", help="sample rate when the recording has no time column "
                   "(and no Fs line)")
    d.add_argument("--scale", type=float, metavar="UNITS_PER_G", help="output units per g, for counts or volts "
                   "(default: the magnitude of the mean output, as a static sensor reads 1 g)")
    a = p.add_argument_group("analysis")
    a.add_argument("--tau-max", type=float, metavar="S", help="longest averaging time τ, s (default: a quarter of "
                   "the stretch)")
    a.add_argument("--ci", type=float, default=0.683, metavar="LEVEL",
                   help="confidence level of the intervals (default 0.683, one sigma)")
    o = p.add_argument_group("output")
    o.add_argument("--json", action="store_true", help="print the analysis as one JSON object (units in the keys)")
    o.add_argument("--plot", metavar="FILE.png", help="write the log-log Allan deviation figure with the read lines")
    o.add_argument("--kalibr-yaml", metavar="FILE.yaml",
                   help="write Kalibr's imu.yaml accelerometer fields (noise density, random walk, update rate; SI)")
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


def run(args) -> int:
    from ..noise import noise_from_recording

    for path, option in ((args.plot, "--plot"), (args.kalibr_yaml, "--kalibr-yaml")):
        refuse_same_file(path, args.recording, option=option)
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
    report = noise_from_recording(args.recording, columns=args.columns, rate=args.rate, units=args.units,
                                  interval=parse_interval(args.interval), scale=args.scale, ci=args.ci,
                                  tau_max_s=args.tau_max)
    # Everything is rendered before anything is written: a failure leaves no partial output behind.
    files: dict[str, bytes] = {}
    if args.kalibr_yaml:
        files[args.kalibr_yaml] = report.kalibr_yaml().encode()
    if args.plot:
        files[args.plot] = report.figure_bytes(fmt)
    for path, content in files.items():
        try:
            Path(path).write_bytes(content)
        except OSError as exc:
            raise InputError(f"cannot write {path}: {exc.strerror or exc}") from None
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
        return 0
    print(report.table())
    for path in files:
        print(f"wrote {path}")
    return 0
