"""optcal simulate: a simulated positions data set (docs/design.md §4, §9.1)."""

from __future__ import annotations

import json

from ..errors import InputError
from ._common import read_json_object, refuse_overwrite

HELP = "simulate static positions of an accelerometer and write a positions CSV (default model nonlinear12)"


def add_arguments(p):
    p.add_argument("--scheme", default="24", help="6, 24, 36 or random:N (default 24)")
    p.add_argument("--model", default="nonlinear12", help="model of the simulated sensor (default nonlinear12)")
    p.add_argument("--truth", help="JSON {name: value}; default: navigation-grade values drawn from --seed")
    p.add_argument("--noise-ug", type=float, default=10.0, help="SD of each position's mean per axis, µg (default 10)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the random draws: truth, random schemes, tilt, noise (default 0)")
    p.add_argument("--tilt-deg", type=float, default=0.0, help="placement error SD per axis, degrees")
    p.add_argument("--temp", help="temperature ramp C1:C2 over the positions, °C")
    p.add_argument("--dwell-s", type=float, help="dwell per position, s (adds time stamps)")
    p.add_argument("--effect", action="append", default=[], metavar="TERM:name=value,...",
                   help="hidden effect the model lacks, e.g. cubic:K3_x=1e-4 (repeatable)")
    p.add_argument("--reference", action="store_true", help="add turntable reference columns ref_x, ref_y, ref_z")
    p.add_argument("--reference-error-arcsec", type=float, default=0.0,
                   help="with --reference: SD per axis of the true orientation about the commanded one, arcsec")
    p.add_argument("--gravity-g", type=float, default=1.0, help="local gravity in g (default 1)")
    p.add_argument("-o", "--output", required=True, help="positions CSV to write")
    p.add_argument("--truth-out", help="also write the full truth (with effects) as JSON")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")


def parse_effects(items: list[str]) -> dict[str, dict[str, float]]:
    from ..model import TERMS

    effects: dict[str, dict[str, float]] = {}
    for item in items:
        term, _, rest = item.partition(":")
        if term not in TERMS:
            raise InputError(f"--effect {item!r}: unknown term {term!r}; terms are {', '.join(TERMS)}")
        params = {}
        for kv in filter(None, rest.split(",")):
            k, _, v = kv.partition("=")
            if k not in TERMS[term].params:
                names = ", ".join(TERMS[term].params)
                raise InputError(f"--effect {item!r}: {k!r} is not a parameter of {term} ({names})")
            try:
                params[k] = float(v)
            except ValueError:
                raise InputError(f"--effect {item!r}: {v!r} is not a number") from None
        if not params:
            example = f"{term}:{TERMS[term].params[0]}=1e-4"
            raise InputError(f"--effect {item!r}: give at least one parameter, e.g. {example}")
        effects[term] = params
    return effects


def run(args) -> int:
    import numpy as np

    from ..model import get_model
    from ..presets import draw_truth
    from ..simulate import simulate

    refuse_overwrite(args.output, args.force)
    refuse_overwrite(args.truth_out, args.force)
    model = get_model(args.model)
    rng = np.random.default_rng(args.seed)
    truth = read_json_object(args.truth, "truth") if args.truth else draw_truth(model, rng)
    unknown = sorted(set(truth) - set(model.names))
    if unknown:
        raise InputError(f"truth has parameter(s) {', '.join(unknown)} that model {model.name} lacks; use --effect "
                         "for hidden terms or a larger --model")
    temp = None
    if args.temp:
        try:
            c1, c2 = (float(v) for v in args.temp.split(":"))
        except ValueError:
            raise InputError(f"--temp {args.temp!r} must be C1:C2, e.g. 20:40") from None
        temp = (c1, c2)
    sim = simulate(
        model, truth, rng, scheme=args.scheme, noise_g=args.noise_ug * 1e-6, tilt_deg=args.tilt_deg, temp=temp,
        times=args.dwell_s is not None, dwell_s=args.dwell_s or 10.0, effects=parse_effects(args.effect),
        reference=args.reference, reference_error_arcsec=args.reference_error_arcsec, g_local=args.gravity_g,
    )
    sim.data.to_csv(args.output)
    if args.truth_out:
        with open(args.truth_out, "w") as fh:
            json.dump(sim.truth, fh, indent=2)
    print(f"wrote {len(sim.data)} positions ({sim.model.name}) to {args.output}")
    return 0
