"""optcal demo: simulate a 24-position data set and calibrate it, printing estimates beside the truth."""

from __future__ import annotations

from optcal.app.commands._common import check_seed, parameter_table
from optcal.core.errors import InputError

HELP = "simulate a 24-position data set and calibrate it (the first end-to-end example; default model nonlinear12)"


def add_arguments(p):
    p.add_argument("--model", default="nonlinear12", help="model simulated and fitted (default nonlinear12)")
    p.add_argument("--scheme", default="24", help="6, 24, 36 or random:N (default 24)")
    p.add_argument("--noise-ug", type=float, default=10.0, help="SD of each position's mean per axis, µg (default 10)")
    p.add_argument("--solver", default="lm", help="registered solver (default lm)")
    p.add_argument("--seed", type=int, default=2020, help="seed of the truth, the noise and the solver (default 2020)")


def run(args) -> int:
    import numpy as np

    from optcal.app.commands.simulate import check_noise_ug
    from optcal.app.fit import calibrate
    from optcal.core.model import get_model
    from optcal.core.presets import draw_truth
    from optcal.core.simulate import simulate

    check_seed(args.seed)
    check_noise_ug(args.noise_ug)
    if args.noise_ug == 0:
        raise InputError("--noise-ug 0: the standard errors need a noise; give the SD of a position mean in µg "
                         "(e.g. 10)")
    model = get_model(args.model)
    rng = np.random.default_rng(args.seed)
    truth = draw_truth(model, rng)
    sim = simulate(model, truth, rng, scheme=args.scheme, noise_g=args.noise_ug * 1e-6)
    cal = calibrate(sim.data, model, solver=args.solver, noise_g=args.noise_ug * 1e-6, seed=args.seed)
    print(f"simulated {len(sim.data)} positions, {args.noise_ug} µg noise, truth drawn from seed {args.seed}")
    print(f"{cal.solver}: residual RMS {cal.fit.rms_g * 1e6:.2f} µg, {cal.result.nfev} evaluations, "
          f"{cal.result.runtime_s * 1e3:.1f} ms")
    print("standard errors are Cramér-Rao bounds at the fitted point for the stated noise")
    print(parameter_table(model.names, cal.x, cal.stderr, truth, units=model.units(sim.data.units)))
    return 0
