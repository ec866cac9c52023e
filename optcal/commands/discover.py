"""optcal discover: find which term the model is missing, add it, and show the residual shrink."""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import InputError
from ._dataopts import add_data_options, gravity_from_args, load_positions

HELP = "discover the terms a model is missing (F-test and BIC, forward selection; default base model linear9)"

# Copies of optcal.discovery's defaults for the help text: importing optcal.discovery (NumPy, the
# calibration problem) would slow every `optcal --help`. tests/test_startup.py checks that they agree.
CANDIDATES = ("quadratic", "cubic", "scale_asymmetry", "cross_coupling", "temperature_bias",
              "temperature_scale", "bias_drift", "misalignment")
DEFAULT_ALPHA = 0.01
DEFAULT_BIC_THRESHOLD = -2.0


def add_arguments(p):
    p.add_argument("data", metavar="POSITIONS.csv", help="positions CSV (or a raw recording with --raw)")
    p.add_argument("--base", default="linear9", help="base model name or sum of terms (default linear9)")
    p.add_argument("--candidates", metavar="TERM,TERM",
                   help=f"terms to try (default: all of {', '.join(CANDIDATES)} not in the base)")
    p.add_argument("--alpha", type=float, default=DEFAULT_ALPHA,
                   help=f"family-wise significance per step, split over the candidates (default {DEFAULT_ALPHA})")
    p.add_argument("--bic-threshold", type=float, default=DEFAULT_BIC_THRESHOLD,
                   help=f"a term must also change BIC by less than this (default {DEFAULT_BIC_THRESHOLD})")
    p.add_argument("--noise", type=float, metavar="G",
                   help="noise of each position's mean per axis in g (default: from n and sx, sy, sz, if present)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    p.add_argument("--plot", metavar="FILE.png", help="write the residual figure (one panel per step)")
    add_data_options(p)


def run(args) -> int:
    from ..discovery.workflow import discover

    if args.plot:
        out = Path(args.plot)
        if out.parent and not out.parent.is_dir():
            raise InputError(f"--plot {args.plot}: directory {out.parent} does not exist; create it or choose "
                             "another path")
        if out.suffix.lower() not in (".png", ".pdf", ".svg"):
            raise InputError(f"--plot {args.plot}: use a .png, .pdf or .svg file name")
    candidates = None if args.candidates is None else [c for c in args.candidates.split(",") if c.strip()]
    g_local = gravity_from_args(args)
    data = load_positions(args, args.data)
    report = discover(data, base=args.base, candidates=candidates, g_local=g_local, alpha=args.alpha,
                      bic_threshold=args.bic_threshold, noise_g=args.noise)
    if args.plot:
        report.plot(args.plot)
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        if isinstance(data.extra, dict) and data.extra.get("detection") is not None:
            from ..recording import describe_detection

            print(describe_detection(data))
        print(report.summary())
        if args.plot:
            print(f"wrote {args.plot}")
    return 0
