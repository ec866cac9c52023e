"""optcal simulate: a simulated positions data set (docs/design.md, "Position schemes", "Positions CSV")."""

from __future__ import annotations

import json
import logging
import math

from optcal.app.commands._common import (
    check_output_folder,
    check_seed,
    read_json_object,
    refuse_overwrite,
    refuse_same_file,
)
from optcal.core.errors import InputError

HELP = ("simulate static positions of an accelerometer and write a positions CSV (default model nonlinear12), or "
        "with --raw a hand-held IMU recording")


def add_arguments(p):
    p.add_argument("--scheme", default="24", help="6, 24, 36, random:N, plan:D12 (planned; docs/planning.md) or a "
                   "scheme file from optcal plan -o (default 24)")
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
    p.add_argument("--raw", action="store_true",
                   help="write a raw recording instead: an IMU turned by hand through --poses poses at 100 Hz (t in "
                        "s, ax ay az in g, gx gy gz in deg/s; each sensor with its own scale and offset), for "
                        "calibrate --raw, imu and apply")
    p.add_argument("--poses", type=int, default=24, help="with --raw: poses held (default 24)")
    p.add_argument("-o", "--output", required=True, help="positions CSV (or with --raw the recording) to write")
    p.add_argument("--truth-out", help="also write the full truth (with effects) as JSON")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")


def parse_effects(items: list[str]) -> dict[str, dict[str, float]]:
    from optcal.core.model import TERMS

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


# The SD of a position mean: a navigation-grade sensor averaged for seconds gives 1 to 100 µg; above 1 mg
# is warned about, above 1 g (a position mean noisier than gravity itself) refused (docs/design.md, "Units and frames").
# Below 1 ng is no sensor's noise but a value in g given in µg (1e-5 for 10 µg).
NOISE_WARN_UG, NOISE_MAX_UG, NOISE_MIN_UG = 1_000.0, 1_000_000.0, 1e-3


def check_noise_ug(noise_ug: float, option: str = "--noise-ug") -> None:
    """A noise SD in µg: finite, not negative, not absurd; a warning when it looks like another unit."""
    if not math.isfinite(noise_ug) or noise_ug < 0:
        raise InputError(f"{option} {noise_ug:g} must be a finite SD of 0 µg or more")
    if 0 < noise_ug < NOISE_MIN_UG:
        raise InputError(f"{option} {noise_ug:g} µg ({noise_ug * 1e-6:g} g) is below any sensor's noise; it looks like "
                         "a value in g: give the SD in µg (10 is typical)")
    if noise_ug > NOISE_MAX_UG:
        raise InputError(f"{option} {noise_ug:g} µg ({noise_ug * 1e-6:g} g) per position mean is noisier than "
                         "gravity itself; give the SD in µg (10 is typical)")
    if noise_ug > NOISE_WARN_UG:
        logging.getLogger("optcal").warning(
            f"{option} {noise_ug:g} µg: {noise_ug / 1000:g} mg per position mean is implausible for a "
            "navigation-grade sensor (1 to 100 µg); the option is in µg")


def check_options(args) -> None:
    """Every number simulate reads, with its unit, before anything is drawn or written."""
    check_seed(args.seed)
    check_noise_ug(args.noise_ug)
    for value, option, unit in ((args.tilt_deg, "--tilt-deg", "deg"),
                                (args.reference_error_arcsec, "--reference-error-arcsec", "arcsec")):
        if not math.isfinite(value) or value < 0:
            raise InputError(f"{option} {value:g} must be a finite SD of 0 {unit} or more")
    if args.tilt_deg > 45:
        raise InputError(f"--tilt-deg {args.tilt_deg:g} is not a placement error; give the SD in degrees (0 to 45)")
    if args.dwell_s is not None and not (math.isfinite(args.dwell_s) and args.dwell_s > 0):
        raise InputError(f"--dwell-s {args.dwell_s:g} must be a positive dwell per position in seconds")
    if args.reference_error_arcsec and not args.reference:
        raise InputError("--reference-error-arcsec is the turntable's error: use it with --reference")
    from optcal.core.gravity import check_gravity_g

    try:
        check_gravity_g(args.gravity_g)
    except InputError as exc:
        raise InputError(f"--gravity-g: {exc}") from None
    refuse_same_file(args.output, args.truth)
    refuse_same_file(args.truth_out, args.truth, args.output, option="--truth-out")
    refuse_overwrite(args.output, args.force)
    refuse_overwrite(args.truth_out, args.force)
    check_output_folder(args.output)
    check_output_folder(args.truth_out, "--truth-out")


RAW_ONLY, RAW_DEFAULTS = ("--poses",), {"scheme": "24", "model": "nonlinear12", "truth": None, "noise_ug": 10.0,
                                           "tilt_deg": 0.0, "temp": None, "dwell_s": None, "effect": [],
                                           "reference": False, "reference_error_arcsec": 0.0, "gravity_g": 1.0,
                                           "truth_out": None}


def run_raw(args) -> int:
    """A hand-held IMU recording (optcal.core.synthetic_imu.handheld_imu, its defaults) as a CSV with a header."""
    import numpy as np

    from optcal.core.atomicfile import EXISTS_OUTPUT, atomic_write
    from optcal.core.synthetic_imu import handheld_imu

    given = [k for k, v in RAW_DEFAULTS.items() if getattr(args, k) != v]
    if given:
        raise InputError(f"--raw simulates a hand-held IMU recording; --{given[0].replace('_', '-')} is for "
                         "positions: leave it out, or leave out --raw")
    check_seed(args.seed)
    if not 6 <= args.poses <= 1000:
        raise InputError(f"--poses {args.poses}: give 6 to 1000 poses (a calibration needs at least 6)")
    refuse_overwrite(args.output, args.force)
    check_output_folder(args.output)
    # re-seats happen with a (short) motion: a pose that jumps while logging pauses is no first example
    sim = handheld_imu(np.random.default_rng(args.seed), n_poses=args.poses, p_reseat_still=0.0)
    table = np.column_stack([sim.acc.t, sim.acc.N, sim.gyro.N])
    body = "\n".join(",".join(f"{v:.7g}" for v in row) for row in table.tolist())
    with atomic_write(args.output, overwrite=args.force, exists=EXISTS_OUTPUT) as f:
        f.write("t,ax,ay,az,gx,gy,gz\n" + body + "\n")
    print(f"wrote a hand-held IMU recording of {args.poses} poses, {len(table)} samples at {sim.acc.rate:g} Hz "
          f"({table[-1, 0]:.1f} s; t in s, ax ay az in g, gx gy gz in deg/s) to {args.output}")
    return 0


def run(args) -> int:
    import numpy as np

    if args.raw:
        return run_raw(args)
    if args.poses != 24:
        raise InputError("--poses is the number of poses of a --raw recording; for positions give --scheme")
    from optcal.core.model import get_model
    from optcal.core.presets import draw_truth
    from optcal.core.simulate import simulate

    check_options(args)
    model = get_model(args.model)
    rng = np.random.default_rng(args.seed)
    truth = read_json_object(args.truth, "truth") if args.truth else draw_truth(model, rng)
    bad = [k for k, v in truth.items() if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)]
    if bad:
        raise InputError(f"truth {args.truth}: {', '.join(bad)} must be finite numbers (the model's parameters in "
                         "their units, docs/design.md, 'Terms and parameters')")
    unknown = sorted(set(truth) - set(model.names))
    if unknown:
        raise InputError(f"truth has parameter(s) {', '.join(unknown)} that model {model.name} lacks; use --effect "
                         "for hidden terms or a larger --model")
    temp = None
    if args.temp:
        try:
            c1, c2 = (float(v) for v in args.temp.split(":"))
        except ValueError:
            raise InputError(f"--temp {args.temp!r} must be C1:C2 in °C, e.g. 20:40") from None
        if not all(math.isfinite(c) and -100 <= c <= 200 for c in (c1, c2)):
            raise InputError(f"--temp {args.temp!r}: give temperatures in °C, between -100 and 200")
        temp = (c1, c2)
    sim = simulate(
        model, truth, rng, scheme=args.scheme, noise_g=args.noise_ug * 1e-6, tilt_deg=args.tilt_deg, temp=temp,
        times=args.dwell_s is not None, dwell_s=args.dwell_s or 10.0, effects=parse_effects(args.effect),
        reference=args.reference, reference_error_arcsec=args.reference_error_arcsec, g_local=args.gravity_g,
    )
    # both files are rendered, then written to temporary files beside them, before either is renamed into place
    from contextlib import ExitStack

    from optcal.core.atomicfile import EXISTS_OUTPUT, atomic_write

    files = {args.output: sim.data.to_csv()}
    if args.truth_out:
        files[args.truth_out] = json.dumps(sim.truth, indent=2)
    with ExitStack() as stack:
        for path, text in files.items():
            stack.enter_context(atomic_write(path, overwrite=args.force, exists=EXISTS_OUTPUT)).write(text)
    print(f"wrote {len(sim.data)} positions ({sim.model.name}, noise {args.noise_ug:g} µg per position mean) "
          f"to {args.output}")
    return 0
