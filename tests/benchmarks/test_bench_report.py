"""Benchmark of a study's report (issue #22: `make run` spent 41-58 s writing the compare study's report, most
of it drawing figures): the report of a 40-group study (ten fast solvers × two models × two schemes, three
runs) with every figure drawn in the report's own process, and with the figures drawn by worker processes
(one per CPU; optcal.studies.figures.Renderer), which is what `optcal study report` does from 40 groups on.

Run with `make bench`. Under `make test` (timing disabled) it is skipped: what it would check there, the
report and its figures drawn both ways, tests/test_report_speed_equivalence.py checks file for file, and a
30-second smoke run would only repeat it. extra_info: the groups, the figures, the workers, the seconds (the
fastest round), and the CPU seconds of the report's own process. No timed assertion.
"""

import shutil
import time

import pytest

from optcal.studies import figures
from optcal.studies.execute import run_study
from optcal.studies.report import write_report
from optcal.studies.spec import parse, tomllib

SOLVERS = ["scipy-lm", "scipy-trf", "nlopt-lbfgs", "nlopt-slsqp", "nlopt-bobyqa", "nlopt-neldermead", "bsas", "pso",
           "casadi-ipopt", "ellipsoid"]
SPEC = """
name = "bench-report"
runs = 3
seed = 7
models = ["nonlinear12", "seed15"]
schemes = ["24", "36"]
tilt_deg = 1.0
budget = 500
[navigation]
enabled = true
""" + "".join(f'[[solvers]]\nname = "{s}"\n' for s in SOLVERS)


@pytest.fixture(scope="module")
def study(tmp_path_factory, request):
    if request.config.getoption("benchmark_disable"):
        pytest.skip("timing disabled: the report drawn both ways is tests/test_report_speed_equivalence.py's test")
    folder = tmp_path_factory.mktemp("bench_report") / "study"
    run_study(parse(tomllib.loads(SPEC), "bench-report.toml"), folder, progress=False)
    return folder


@pytest.mark.parametrize("mode", ["here", "workers"])
def test_bench_report(benchmark, study, tmp_path, mode):
    folder = tmp_path / "study"
    shutil.copytree(study, folder)
    n_groups = 2 * 2 * len(SOLVERS)
    workers = 0 if mode == "here" else figures.figure_workers(n_groups)
    cpu = []

    def report():
        c = time.process_time()
        out = write_report(folder, workers=workers)
        cpu.append(time.process_time() - c)
        return out

    out = benchmark.pedantic(report, rounds=3, iterations=1, warmup_rounds=0)
    text = out.read_text()
    drawn = sorted(p.name for p in (folder / "figures").glob("*.png"))
    assert n_groups >= figures.PARALLEL_MIN_GROUPS and "## seed15, 36 positions" in text
    assert len(drawn) >= 5 * 4 + 4 and all(f"figures/{n}" in text for n in drawn)
    seconds = benchmark.stats.stats.min if benchmark.stats is not None else None
    benchmark.extra_info.update({"groups": n_groups, "figures": len(drawn), "workers": workers,
                                 "seconds": seconds, "report_process_cpu_s": min(cpu)})
