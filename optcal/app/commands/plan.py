"""optcal plan: plan the positions of a calibration, or advise the next one; with ``--sensor gyroscope``, plan the
order of a scheme's poses and the rotations between them for the gyroscope (docs/planning.md)."""

from __future__ import annotations

import json

from optcal.app.commands._common import check_seed, refuse_overwrite, refuse_same_file
from optcal.app.commands._dataopts import add_data_options, gravity_from_args, load_positions
from optcal.core.errors import InputError

HELP = ("plan N calibration positions (D-, A-, E-optimal or to targets), advise the next pose for recorded ones, or "
        "plan the rotations between poses for the gyroscope")
GYRO_OPTIONS = ("scheme", "gyro_model", "order", "rotations", "gyro_noise", "rest_s", "rate_limit", "motion_budget",
                "headings")


def add_arguments(p):
    p.add_argument("--sensor", choices=("accelerometer", "gyroscope"), default="accelerometer",
                   help="accelerometer: plan the positions (default); gyroscope: plan the order of a scheme's poses "
                   "and the rotation between each two (docs/planning.md, 'Planning the rotations')")
    p.add_argument("--n", type=int, metavar="N", help="number of positions to plan")
    p.add_argument("--model", default="nonlinear12", help="model name or sum of terms (default nonlinear12)")
    p.add_argument("--criterion", default="D", choices=("D", "A", "E", "targets", "worst"),
                   help="D: log-det of the information; A: mean variance; E: worst direction; targets: every "
                   "SD within its target (accelerometer); worst: the largest parameter variance (gyroscope; "
                   "default D)")
    p.add_argument("--targets", metavar="LIST", help="SD targets, e.g. 'scale<=20ppm,bias<=30ug' (units: ppm for "
                   "scale, ug or mg for bias, urad, arcsec or deg for misalignment, ppm/g for quadratic)")
    p.add_argument("--noise-ug", type=float, help="SD of each position's (gyroscope: rest's) mean per axis, µg "
                   "(default 10; with --recorded: the data's own when they have sx, sy, sz)")
    p.add_argument("--fixture", default="free",
                   help="free (hand-held, default), faces (a cube's six faces), faces:STEP (a cube on a tilt "
                   "plate, tilts in STEP degrees) or head:STEP (a dividing head about each axis)")
    p.add_argument("--solver", default="cmaes", help="registered search method for the design problem, or "
                   "'exchange' for the exchange algorithm alone (default cmaes; the exchange always runs as a check)")
    p.add_argument("--starts", type=int, help="independent random starts of the solver (default 2; gyroscope: "
                   "starting orders, the scheme's and random ones, default 8)")
    p.add_argument("--budget", type=int, default=5000, help="cost evaluations per start (default 5000)")
    p.add_argument("--placement-deg", type=float, default=3.0,
                   help="placement error SD per axis for the robustness score, degrees (default 3; 0: none)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random draw (default 0)")
    p.add_argument("--recorded", metavar="DATA", help="positions recorded so far (positions CSV, or a raw "
                   "recording with --raw): advise the next pose and say whether the targets are met")
    p.add_argument("--json", action="store_true", help="print the plan or the advice as one JSON object")
    p.add_argument("-o", "--output", metavar="SCHEME.csv", help="write the planned scheme (read by --scheme of "
                   "simulate, info and study specs)")
    p.add_argument("--plot", metavar="FILE.png", help="figure of the directions on the sphere")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    g = p.add_argument_group("gyroscope (with --sensor gyroscope)")
    g.add_argument("--scheme", help="the poses: 6, 24, 36, random:N, plan:D18 or a scheme file (default 24)")
    g.add_argument("--gyro-model", help="gyro9 (scale factors and misalignments, the bias from the rests), gyro12 "
                   "(and the bias; default) or gyro21 (and g-sensitivity)")
    g.add_argument("--order", choices=("plan", "given"), help="plan the order of the poses (default) or keep the "
                   "scheme's")
    g.add_argument("--rotations", choices=("plan", "axes", "shortest"), help="plan each motion's rotation (default), "
                   "plan it among the turns about the sensor's own axes (easiest by hand), or take the shortest")
    g.add_argument("--gyro-noise", type=float, metavar="DPS_RTHZ", help="the gyroscope's rate noise density, "
                   "°/s/√Hz (default 0.0057, i.e. 1e-4 rad/s/√Hz)")
    g.add_argument("--rest-s", type=float, metavar="S", help="each rest's time, s (default 3)")
    g.add_argument("--rate-limit", type=float, metavar="DPS", help="the peak rate of a motion, °/s: a turn by θ "
                   "takes 2θ/limit, at least 0.5 s (default 90)")
    g.add_argument("--motion-budget", type=float, metavar="S", help="at most this much time in motion in all, s "
                   "(default: no limit)")
    g.add_argument("--headings", type=int, metavar="H", help="turns about the vertical tried per pair of poses "
                   "(default 8), besides the turns about the sensor's axes")
    add_data_options(p)


def _criterion(args, model_names_only=False):
    import numpy as np

    from optcal.core.plan.criteria import Criterion, parse_targets
    from optcal.core.plan.fisher import InformationModel

    noise = 10.0 if args.noise_ug is None else args.noise_ug
    if not (np.isfinite(noise) and noise > 0):
        raise InputError(f"--noise-ug {noise:g}: give the SD of a position mean in µg, a positive number (e.g. 10)")
    info = InformationModel.of(args.model, noise * 1e-6)
    targets = parse_targets(args.targets, info.names) if args.targets else {}
    if args.criterion == "targets" and not targets:
        raise InputError("--criterion targets needs --targets, e.g. --targets 'scale<=20ppm,bias<=30ug'")
    return Criterion(info, args.criterion, targets)


def _sd_rows(crit, sd) -> list[dict]:
    import numpy as np

    units = crit.info.model.units("g")
    obs = _observable(crit)
    rows = []
    for i, n in enumerate(crit.info.names):
        t = crit.targets.get(n)
        rows.append({"name": n, "sd": float(sd[i]) if np.isfinite(sd[i]) else None, "unit": units[n],
                     "observable": bool(obs[i]), "target": t,
                     "met": None if t is None or not np.isfinite(sd[i]) else bool(sd[i] <= t)})
    return rows


def _observable(crit):
    import numpy as np

    Q = crit.info.basis
    null = np.eye(len(Q)) - Q @ Q.T
    return np.max(np.abs(null), axis=1) < 1e-3


def _print_sd(rows) -> None:
    print(f"{'parameter':<10} {'Cramér-Rao SD':>14} {'target':>10}  unit (outputs in g)")
    for r in rows:
        sd = "unobservable" if not r["observable"] else ("not determined" if r["sd"] is None else f"{r['sd']:.3e}")
        tgt = "" if r["target"] is None else f"{r['target']:.3g}"
        met = "" if r["met"] is None else ("  met" if r["met"] else "  NOT met")
        print(f"{r['name']:<10} {sd:>14} {tgt:>10}  {r['unit']}{met}")


def run(args) -> int:
    check_seed(args.seed)
    if args.sensor == "gyroscope":
        return _plan_gyro(args)
    given = [f"--{o.replace('_', '-')}" for o in GYRO_OPTIONS if getattr(args, o) is not None]
    if given:
        raise InputError(f"{', '.join(given)} plan the gyroscope's rotations; add --sensor gyroscope")
    if args.criterion == "worst":
        raise InputError("--criterion worst is the gyroscope's; for the accelerometer use D, A, E or targets")
    if args.starts is None:
        args.starts = 2
    if args.recorded:
        return _advise(args)
    if args.n is None:
        raise InputError("give --n N, the number of positions to plan, or --recorded DATA for the next pose")
    refuse_overwrite(args.output, args.force)
    refuse_overwrite(args.plot, args.force)
    refuse_same_file(args.output, args.plot, option="-o")
    import numpy as np

    from optcal.app.workflows.plan import solve_design
    from optcal.core.plan.fixtures import handling_order, to_faces, turn_angle_deg
    from optcal.core.plan.robust import placement_score
    from optcal.core.plan.schemefile import scheme_csv
    from optcal.core.plan.sequential import check_reachable

    if args.plot:
        from optcal.core.plots import check_figure_path

        check_figure_path(args.plot)
    if args.budget is not None and args.budget < 1:
        raise InputError(f"--budget {args.budget}: give at least 1 evaluation per start")
    crit = _criterion(args)
    from optcal.core.plan.design import _check_n

    _check_n(crit, args.n)
    check_reachable(crit, fixture=args.fixture)
    rng = np.random.default_rng(args.seed)
    design, record = solve_design(crit, args.n, fixture=args.fixture, solver=args.solver, starts=args.starts,
                                  budget=args.budget, rng=rng)
    order = handling_order(design.directions)
    d = design.directions[order]
    score = placement_score(crit, d, args.placement_deg, np.random.default_rng(args.seed)) if args.placement_deg > 0 \
        else None
    faces, alpha, beta = to_faces(d)
    rows = _sd_rows(crit, design.sd)
    comments = [f"optcal plan: {args.n} positions, model {crit.info.model.name}, criterion {crit.label()} = "
                f"{design.value:.6g}, noise {crit.info.noise_g * 1e6:g} µg, fixture {args.fixture}, {design.method}, "
                f"seed {args.seed}",
                "dx, dy, dz: unit specific-force direction in the sensor frame; face_down, alpha_deg, beta_deg: "
                "docs/planning.md, 'For a person: fixtures, faces and tilts, order, files, figure'"]
    if args.output:
        from optcal.core.atomicfile import EXISTS_OUTPUT, write_atomic

        write_atomic(args.output, scheme_csv(d, comments), overwrite=args.force, encoding="utf-8", exists=EXISTS_OUTPUT)
    if args.plot:
        from optcal.core.plan.figure import plan_figure
        from optcal.core.plots import save_figure

        save_figure(plan_figure(d, f"{args.n} positions, {crit.label()}-optimal for {crit.info.model.name} "
                                   f"({args.fixture})"), args.plot)
    if args.json:
        unit = ("1 (largest SD/target)" if crit.kind == "targets" else
                "variance in natural units, squared (relative for K, g for b, rad for S, 1/g for K2)")
        out = {"n_positions": args.n, "model": crit.info.model.name, "criterion": crit.kind,
               "criterion_value": design.value, "criterion_unit": unit,
               "noise_ug": crit.info.noise_g * 1e6, "fixture": args.fixture, "method": design.method,
               "solver_record": record, "turn_deg": turn_angle_deg(d),
               "positions": [{"position": i + 1, "dx": float(x), "dy": float(y), "dz": float(z), "face_down": f,
                              "alpha_deg": float(a), "beta_deg": float(b)}
                             for i, ((x, y, z), f, a, b) in enumerate(zip(d, faces, alpha, beta))],
               "crlb": rows, "placement": None if score is None else score.to_dict()}
        print(json.dumps(out, indent=2))
        return 0
    print(comments[0])
    if args.solver != "exchange":
        starts = ", ".join(f"{v:.6g}" for v in record["starts"])
        print(f"  {args.solver} from {len(record['starts'])} random starts: {starts}; "
              f"{'refined' if record['refined'] else 'best'} {record['solver_value']:.6g}; exchange check: "
              f"{record['exchange']:.6g}")
    print(f"positions in handling order (total turn {turn_angle_deg(d):.0f}°); A_i = sin β, A_j = cos β sin α, "
          "±A_k = cos β cos α:")
    print(f"{'#':>3} {'face down':>9} {'α °':>7} {'β °':>7}   {'dx':>9} {'dy':>9} {'dz':>9}")
    for i, ((x, y, z), f, a, b) in enumerate(zip(d, faces, alpha, beta)):
        print(f"{i + 1:>3} {f:>9} {a:7.1f} {b:7.1f}   {x:9.5f} {y:9.5f} {z:9.5f}")
    _print_sd(rows)
    if score is not None:
        line = (f"placement error {score.sigma_deg:g}° per axis ({score.draws} draws): criterion {score.planned:.4g} "
                f"planned, {score.mean:.4g} expected, {score.p95:.4g} at the 95th percentile")
        if score.p_miss is not None:
            line += f"; targets missed in {100 * score.p_miss:.0f} % of placements"
        print(line)
        if score.fragile:
            print("FRAGILE: this design loses more than 10 % of its criterion (or its targets) under the stated "
                  "placement error; place more carefully, or plan with more positions")
    return 0


def _advise(args) -> int:
    import numpy as np

    from optcal.core.plan.fixtures import to_faces
    from optcal.core.plan.sequential import next_best, progress, recorded_directions

    if args.output or args.plot:
        raise InputError("-o and --plot write a plan; with --recorded, the advice is printed (use --json to keep it)")
    data = load_positions(args, args.recorded)
    if args.noise_ug is None:
        from optcal.core.problem import CalibrationProblem

        p = CalibrationProblem(args.model, data, g_local=gravity_from_args(args), check=False, fix_gauge=False)
        if p.noise_g is not None:
            args.noise_ug = p.noise_g * 1e6
    crit = _criterion(args)
    dirs = recorded_directions(crit.info.model, data, gravity_from_args(args))
    prog = progress(crit, dirs)
    nxt, val = next_best(crit, dirs, fixture=args.fixture)
    faces, a, b = to_faces(nxt[None])
    rows = _sd_rows(crit, prog.sd)
    determined = np.isfinite(prog.value)
    if args.json:
        print(json.dumps({"recorded": prog.n, "noise_ug": crit.info.noise_g * 1e6, "determined": bool(determined),
                          "criterion": crit.kind, "criterion_value": prog.value if determined else None,
                          "targets_met": None if prog.met is None else prog.enough, "crlb": rows,
                          "next": {"dx": float(nxt[0]), "dy": float(nxt[1]), "dz": float(nxt[2]), "face_down": faces[0],
                                   "alpha_deg": float(a[0]), "beta_deg": float(b[0]),
                                   "criterion_after": val}}, indent=2))
        return 0
    print(f"{prog.n} positions recorded; model {crit.info.model.name}, noise {crit.info.noise_g * 1e6:.4g} µg per axis")
    if not determined:
        print(f"not enough yet: these positions do not determine the model ({crit.info.n_observable} observable "
              "combinations); add the poses advised")
    else:
        print(f"criterion {crit.label()} = {prog.value:.4g}")
        _print_sd(rows)
        if prog.met is not None:
            print("enough: every target is met" if prog.enough else
                  f"not enough yet: {int(np.sum(~prog.met))} target(s) missed")
    print(f"next pose: face {faces[0]} down, α = {a[0]:.1f}°, β = {b[0]:.1f}° "
          f"(direction {nxt[0]:.4f}, {nxt[1]:.4f}, {nxt[2]:.4f})")
    return 0


def _plan_gyro(args) -> int:
    """--sensor gyroscope: the order of a scheme's poses and the rotation of each motion (optcal.core.gyro.plan)."""
    import numpy as np

    from optcal.core.gyro.model import get_gyro_model
    from optcal.core.gyro.plan import CRITERIA, GyroNoise, Timing, model_spec
    from optcal.core.gyro.plan_candidates import candidates
    from optcal.core.gyro.plan_follow import plan_csv, summary, verdict
    from optcal.core.gyro.plan_search import habitual, search
    from optcal.core.schemes import scheme

    for value, name in ((args.n, "--n"), (args.recorded, "--recorded"), (args.plot, "--plot"),
                        (args.targets, "--targets")):
        if value is not None:
            raise InputError(f"{name} plans the accelerometer's positions; with --sensor gyroscope give the poses "
                             "with --scheme")
    if args.criterion not in CRITERIA:
        raise InputError(f"--criterion {args.criterion} is the accelerometer's; for the gyroscope use "
                         f"{', '.join(CRITERIA)}")
    refuse_overwrite(args.output, args.force)
    refuse_same_file(args.output, args.scheme)
    model = args.gyro_model or "gyro12"
    g_sens, bias = model_spec(model)
    noise_ug = 10.0 if args.noise_ug is None else args.noise_ug
    density = 1e-4 if args.gyro_noise is None else float(np.deg2rad(args.gyro_noise))
    noise = GyroNoise(density, noise_ug * 1e-6, 3.0 if args.rest_s is None else args.rest_s)
    timing = Timing(90.0 if args.rate_limit is None else args.rate_limit)
    rng = np.random.default_rng(args.seed)
    spec = args.scheme or "24"
    d = scheme(spec, rng)
    p = get_gyro_model(g_sens, bias == "fit").n_params
    residuals = 2 * (len(d) - 1) + (3 * len(d) if bias == "fit" else 0)
    if len(d) < 2 or residuals < p:
        raise InputError(f"{len(d)} pose(s) give {residuals} residuals, fewer than the {p} parameters of {model}: "
                         "give a scheme with more poses")
    cands = candidates(d, model, noise=noise, timing=timing, headings=8 if args.headings is None else args.headings,
                       rng=rng)
    plan = search(cands, args.criterion, order=args.order or "plan", rotations=args.rotations or "plan",
                  restarts=8 if args.starts is None else args.starts, budget_s=args.motion_budget, rng=rng)
    rank = verdict(plan.directions, plan.rotvec, plan.duration, model, noise, rng)  # names what is undetermined
    if not np.isfinite(plan.value):
        raise InputError(f"the plan leaves {model} nearly undetermined (its information is singular to the "
                         "observability threshold); give more poses, or a model with fewer parameters")
    try:
        hab = habitual(cands, kind=args.criterion)
    except InputError:  # the scheme's order puts opposite poses side by side: no habitual plan to compare with
        hab = None
    settings = (f"scheme {spec}, {len(d)} poses, model {model}, criterion {args.criterion}, order "
                f"{args.order or 'plan'}, rotations {args.rotations or 'plan'}, rate limit {timing.rate_limit_dps:g} "
                f"°/s, noise {np.rad2deg(density):.3g} °/s/√Hz and {noise_ug:g} µg per rest mean, rests "
                f"{noise.rest_s:g} s, seed {args.seed}")
    out = summary(plan, hab, rank)
    if args.output:
        from optcal.core.atomicfile import EXISTS_OUTPUT, write_atomic

        write_atomic(args.output, plan_csv(plan, [f"optcal plan --sensor gyroscope: {settings}",
                                                  f"criterion {args.criterion} = {plan.value:.6g} (variance in "
                                                  "natural units), motions "
                                                  f"{plan.motion_s:.2f} s, session {plan.session_s:.2f} s"]),
                     overwrite=args.force, encoding="utf-8", exists=EXISTS_OUTPUT)
    if args.json:
        out["settings"] = settings
        print(json.dumps(out, indent=2))
        return 0
    _print_gyro(settings, out)
    return 0


def _z(v: float, digits: int) -> float:
    """``v`` rounded to ``digits`` decimals, without the sign of a rounded-away negative ("-0.0")."""
    return round(v, digits) + 0.0


def _print_gyro(settings: str, out: dict) -> None:
    print(f"optcal plan --sensor gyroscope: {settings}")
    print(f"criterion {out['criterion']} = {out['criterion_value']:.4g}, a {out['criterion_unit']}; motions "
          f"{out['motion_s']:.1f} s, session {out['session_s']:.1f} s")
    h = out.get("habitual")
    if h:
        print(f"habitual plan (the scheme's order, shortest rotations): {h['criterion_value']:.4g}, motions "
              f"{h['motion_s']:.1f} s, session {h['session_s']:.1f} s; this plan's criterion is {h['factor']:.3g} "
              "times lower")
    print(f"{'#':>3} {'face down':>9} {'α °':>7} {'β °':>7}   {'dx':>8} {'dy':>8} {'dz':>8}   then turn about axis "
          "(sensor frame)       angle °  time s  peak °/s")
    for pose, m in zip(out["poses"], out["motions"] + [None], strict=True):
        line = (f"{pose['position']:>3} {pose['face_down']:>9} {_z(pose['alpha_deg'], 1):7.1f} "
                f"{_z(pose['beta_deg'], 1):7.1f}   {_z(pose['dx'], 4):8.4f} {_z(pose['dy'], 4):8.4f} "
                f"{_z(pose['dz'], 4):8.4f}")
        if m:
            ax = "(" + ", ".join(f"{_z(v, 4):7.4f}" for v in m["axis"]) + ")"
            line += (f"   {ax} {m['about'] or '':>3}  {m['angle_deg']:7.1f}  {m['duration_s']:6.2f}  "
                     f"{m['peak_dps']:8.1f}")
        print(line)
    print(f"{'parameter':<10} {'Cramér-Rao SD':>14}  unit")
    for r in out["crlb"]:
        print(f"{r['name']:<10} {r['sd']:>14.4g}  {r['unit']}")
    print(f"observability: all {out['n_parameters']} parameters determined (rank {out['rank']} of "
          f"{out['n_parameters']}) by a recording that follows the plan")
