"""optcal discover: find which term the model is missing, add it, and show the residual shrink; then the residual
diagnostics and the generated dictionary of effects the list lacks (docs/discovery.md)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from optcal.app.commands._common import refuse_overwrite, refuse_same_file
from optcal.app.commands._dataopts import add_data_options, gravity_from_args, load_positions
from optcal.core.errors import InputError

HELP = ("discover the terms a model is missing (F-test and BIC, forward selection over the list and a generated "
        "dictionary of effects it lacks; residual diagnostics; default base model linear9)")

# Copies of optcal.core.discovery's defaults for the help text: importing optcal.core.discovery (NumPy, the
# calibration problem) would slow every `optcal --help`. tests/test_startup.py checks that they agree.
CANDIDATES = ("quadratic", "cubic", "scale_asymmetry", "cross_coupling", "temperature_bias",
              "temperature_scale", "bias_drift", "misalignment")
DEFAULT_ALPHA = 0.01
DEFAULT_BIC_THRESHOLD = -2.0
MAX_DICTIONARY_TERMS = 4


def add_arguments(p):
    p.add_argument("data", metavar="POSITIONS.csv", help="positions CSV (or a raw recording with --raw)")
    p.add_argument("--base", default="linear9", help="base model name or sum of terms (default linear9)")
    p.add_argument("--candidates", metavar="TERM,TERM",
                   help=f"terms to try (default: all of {', '.join(CANDIDATES)} not in the base)")
    p.add_argument("--alpha", type=float, default=DEFAULT_ALPHA,
                   help=f"family-wise significance per step, split over the candidates (default {DEFAULT_ALPHA})")
    p.add_argument("--bic-threshold", type=float, default=DEFAULT_BIC_THRESHOLD,
                   help=f"a term must also change BIC by less than this (default {DEFAULT_BIC_THRESHOLD})")
    p.add_argument("--noise-ug", type=float, metavar="UG",
                   help="noise of each position's mean per axis, µg (default: from n and sx, sy, sz, if present)")
    p.add_argument("--json", action="store_true",
                   help="print the report as one JSON object (with the final parameters' units)")
    p.add_argument("--dictionary", action=argparse.BooleanOptionalAction, default=None,
                   help="also search the generated dictionary of effects the list lacks (products and powers of the "
                   "axes, temperature and time powers, sinusoids, the previous pose; default: yes, unless "
                   "--candidates names the terms to try)")
    p.add_argument("--max-dictionary-terms", type=int, default=MAX_DICTIONARY_TERMS, metavar="N",
                   help=f"add at most N terms from the dictionary (default {MAX_DICTIONARY_TERMS})")
    p.add_argument("--plot", metavar="FILE.png", help="write the residual figure (one panel per step)")
    p.add_argument("--diagnostics", metavar="FILE.png",
                   help="write the residual diagnostics' figure (orientation, temperature, time, periodogram, "
                   "order, duration)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --plot or --diagnostics file")
    add_data_options(p)


def run(args) -> int:
    from optcal.app.workflows.discovery import discover

    noise_g = None
    if args.noise_ug is not None:
        from optcal.app.commands.simulate import check_noise_ug

        if args.noise_ug == 0:
            raise InputError("--noise-ug 0: the noise of a position mean is never zero; give it in µg (e.g. 10) "
                             "or leave it out to take it from n and sx, sy, sz")
        check_noise_ug(args.noise_ug)
        noise_g = args.noise_ug * 1e-6
    for option, path in (("--plot", args.plot), ("--diagnostics", args.diagnostics)):
        if path:
            _check_figure(option, path, args)
    if args.plot and args.diagnostics and Path(args.plot).resolve() == Path(args.diagnostics).resolve():
        raise InputError("--plot and --diagnostics name the same file; give each figure its own")
    if args.max_dictionary_terms < 0:
        raise InputError(f"--max-dictionary-terms {args.max_dictionary_terms}: give 0 or more (0: no dictionary terms)")
    candidates = None if args.candidates is None else [c for c in args.candidates.split(",") if c.strip()]
    g_local = gravity_from_args(args)
    data = load_positions(args, args.data)
    if len(data) > 1 and not (data.N.max(axis=0) - data.N.min(axis=0)).any():
        raise InputError(f"{args.data}: all {len(data)} positions have the same outputs, so they test no term; "
                         "record the sensor in varied orientations")
    report = discover(data, base=args.base, candidates=candidates, g_local=g_local, alpha=args.alpha,
                      bic_threshold=args.bic_threshold, noise_g=noise_g, dictionary=args.dictionary,
                      max_dictionary_terms=args.max_dictionary_terms)
    if args.plot:
        report.plot(args.plot)
    if args.diagnostics:
        report.plot_diagnostics(args.diagnostics)
    if args.json:
        final = report.final_model  # units beside final_parameters (docs/design.md, "Units and frames")
        print(json.dumps({**report.to_dict(), "units": final.units(data.units), "output_units": data.units},
                         indent=2))
    else:
        if isinstance(data.extra, dict) and data.extra.get("detection") is not None:
            from optcal.core.recording import describe_detection

            print(describe_detection(data))
        print(report.summary())
        units = report.final_model.units(data.units)
        print(f"units (outputs in {data.units}): " + ", ".join(f"{n} {u}" for n, u in units.items()))
        for path in (args.plot, args.diagnostics):
            if path:
                print(f"wrote {path}")
    return 0


def _check_figure(option: str, path: str, args) -> None:
    """Refuse a figure path before anything is computed: the data file itself, an existing file without --force,
    a missing folder or a suffix that is not an image's."""
    refuse_same_file(path, args.data, option=option)
    refuse_overwrite(path, args.force)
    out = Path(path)
    if out.parent and not out.parent.is_dir():
        raise InputError(f"{option} {path}: directory {out.parent} does not exist; create it or choose another path")
    if out.suffix.lower() not in (".png", ".pdf", ".svg"):
        raise InputError(f"{option} {path}: use a .png, .pdf or .svg file name")
