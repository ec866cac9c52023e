"""Benchmarks of static navigation (optcal.nav): one 5-hour and one 24-hour run at the default 10 s
output step, and a 5-hour run at 100 Hz (1.8·10⁶ samples). The error model is linear and time-invariant,
so each run is one matrix exponential plus log2(n) vectorised products; extra_info holds the errors."""

import math

import pytest

from optcal.gravity import G0, normal_gravity
from optcal.nav import radii, static_navigation

DF = 100e-6 * G0  # a 100 µg north accelerometer error


@pytest.mark.parametrize("hours, dt_s", [(5.0, None), (24.0, None), (5.0, 0.01)])
def test_bench_static_navigation(benchmark, hours, dt_s):
    r = benchmark(static_navigation, [DF, 0.0, 0.0], hours=hours, latitude_deg=45.0, dt_s=dt_s)
    peak = radii(45.0)[0] * 2 * DF / normal_gravity(45.0) / 1852.0  # the Schuler peak R·2δf/g
    assert r.max_error_nmi == pytest.approx(peak, rel=0.01)
    assert len(r.t_s) == int(round(hours * 3600 / (dt_s or 10.0))) + 1
    benchmark.extra_info.update(
        max_error_nmi=r.max_error_nmi, mean_error_nmi=r.mean_error_nmi, samples=len(r.t_s),
        schuler_peak_nmi=peak, hours=hours,
    )
    assert math.isfinite(r.mean_error_nmi)
