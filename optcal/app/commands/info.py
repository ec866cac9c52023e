"""optcal info: observability and Cramér-Rao bounds of a scheme and model, without data."""

from __future__ import annotations

import json

from optcal.app.commands._common import add_noise_from_options, check_seed, describe_noise, noise_from_args
from optcal.core.errors import InputError

HELP = "observability and Cramér-Rao table for a scheme and model (default scheme 24, model seed15)"


def add_arguments(p):
    p.add_argument("--scheme", default="24", help="6, 24, 36, random:N, plan:D12 (planned; docs/planning.md) or a "
                   "scheme file from optcal plan -o (default 24)")
    p.add_argument("--model", default="seed15", help="model name or sum of terms (default seed15)")
    p.add_argument("--noise-ug", type=float, help="SD of each position's mean per axis, µg (default 10)")
    add_noise_from_options(p, "dwell per position, s (needed with --noise-from)",
                           "outputs in g; other units: optcal noise --json first")
    p.add_argument("--seed", type=int, default=0, help="seed for random schemes")
    p.add_argument("--json", action="store_true", help="print the table as one JSON object")


def run(args) -> int:
    import numpy as np

    from optcal.core.analysis import crlb, observability
    from optcal.core.model import get_model
    from optcal.core.presets import PAPER_TRUTH
    from optcal.core.problem import CalibrationProblem
    from optcal.core.simulate import simulate

    check_seed(args.seed)
    if args.noise_ug is not None:
        from optcal.app.commands.simulate import check_noise_ug

        if args.noise_ug == 0:
            raise InputError("--noise-ug 0: with no noise every bound is zero; give the SD of a position mean in µg "
                             "(e.g. 10)")
        check_noise_ug(args.noise_ug)
    if args.dwell_s is not None and not (args.dwell_s > 0 and np.isfinite(args.dwell_s)):
        raise InputError(f"--dwell-s {args.dwell_s:g} must be a positive dwell per position in seconds")
    if args.dwell_s is not None and not args.noise_from:
        raise InputError("--dwell-s sets the dwell for --noise-from; give --noise-from too, or leave it out")
    noise = None
    if args.noise_from:
        if args.noise_ug is not None:
            raise InputError("give the noise either as --noise-ug or as --noise-from, not both")
        if args.dwell_s is None:
            raise InputError("--noise-from needs the dwell per position: give --dwell-s")
        sigma, noise = noise_from_args(args)
        args.noise_ug = sigma * 1e6
    elif args.noise_ug is None:
        args.noise_ug = 10.0
    model = get_model(args.model)
    # Noise-free data at a representative truth: the 2020-paper-like values where the model has them.
    truth = {n: PAPER_TRUTH.get(n, 1.0 if n.startswith("K_") else 0.0) for n in model.names}
    sim = simulate(model, truth, np.random.default_rng(args.seed), scheme=args.scheme, noise_g=0.0,
                   times="t" in model.needs, temp=(20.0, 40.0) if "temp" in model.needs else None)
    problem = CalibrationProblem(model, sim.data, check=False)
    x = sim.truth_vector(model)
    obs = observability(problem, x)
    sd, mask = crlb(problem, x, args.noise_ug * 1e-6)
    # the representative truth's outputs are in g (K = 1): the bounds are in those parameter units (design.md, "Units
    # and frames")
    units = model.units("g")
    if args.json:
        out = {"scheme": args.scheme, "model": model.name, "noise_ug": args.noise_ug, "n_positions": len(sim.data),
               **obs.to_dict(),
               "crlb": {n: (float(s) if np.isfinite(s) else None) for n, s in zip(model.names, sd)},
               "units": units, "output_units": "g",
               **({"noise_from": noise} if noise else {})}
        print(json.dumps(out, indent=2))
        return 0
    print(f"scheme {args.scheme} ({len(sim.data)} positions), model {model.name}, "
          f"noise {args.noise_ug:.4g} µg per axis")
    print("observability: " + obs.describe())
    if noise:
        print(describe_noise(noise))
    print(f"{'parameter':<10} {'Cramér-Rao SD':>14} unit (outputs in g)")
    for n, s in zip(model.names, sd):
        print(f"{n:<10} {s:14.3e} {units[n]}" if np.isfinite(s) else f"{n:<10} {'unobservable':>14}")
    return 0
