"""Benchmarks of static navigation (optcal.core.nav): one 5-hour and one 24-hour run at the default 10 s
output step, a 5-hour run at 100 Hz (1.8·10⁶ samples), and a 5-hour run with the per-site matrix
exponential recomputed (cold cache). The error model is linear and time-invariant, so a run is one
(cached) matrix exponential plus log2(n) vectorised products; extra_info holds the errors."""

import pytest

from optcal.core import nav
from optcal.core.gravity import G0, normal_gravity
from optcal.core.nav import radii, static_navigation

DF = 100e-6 * G0  # a 100 µg north accelerometer error
PEAK = radii(45.0)[0] * 2 * DF / normal_gravity(45.0) / 1852.0  # the Schuler peak R·2δf/g, nmi


def _check(benchmark, r, hours, dt_s):
    assert r.max_error_nmi == pytest.approx(PEAK, rel=0.01)
    assert len(r.t_s) == int(round(hours * 3600 / (dt_s or 10.0))) + 1
    assert 0.3 * PEAK < r.mean_error_nmi < 0.7 * PEAK
    benchmark.extra_info.update(max_error_nmi=r.max_error_nmi, mean_error_nmi=r.mean_error_nmi,
                                samples=len(r.t_s), schuler_peak_nmi=PEAK, hours=hours)


@pytest.mark.parametrize("hours, dt_s", [(5.0, None), (24.0, None), (5.0, 0.01)])
def test_bench_static_navigation(benchmark, hours, dt_s):
    r = benchmark(static_navigation, [DF, 0.0, 0.0], hours=hours, latitude_deg=45.0, dt_s=dt_s)
    _check(benchmark, r, hours, dt_s)


def test_bench_static_navigation_cold_cache(benchmark):
    r = benchmark.pedantic(static_navigation, args=([DF, 0.0, 0.0],), kwargs=dict(hours=5.0, latitude_deg=45.0),
                           setup=nav._site_step.cache_clear, rounds=30)
    _check(benchmark, r, 5.0, None)
