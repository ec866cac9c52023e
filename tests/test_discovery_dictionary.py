"""Discovery of effects the candidate list lacks (issue 31, docs/discovery.md): on simulated data each of ten hidden
effects outside the list is named by its formula and the residual falls to what the data without it leave; on data
without an effect nothing is named in at least 95 % of seeds; the honest ends (what remains when nothing closes the
gap, what to record without a floor)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from optcal import simulate
from optcal.app.workflows.discovery import discover, fit_model
from optcal.core.discovery import EXPLAINED, REMAINS, UNKNOWN
from optcal.core.model import TERMS, get_model
from optcal.core.presets import draw_truth

NOISE = 10e-6

# Each hidden effect: its term (a user-defined term, docs/discovery.md "Names"), the shape of its parameters
# and a size that lifts the base model's noise-free residual RMS to about 30 µg, three times the noise (as
# tests/test_discovery.py's list terms); the time one to 88 µg, since a linear drift of the list takes most of
# a quadratic one and the rest must still show.
EFFECTS = {
    "temp2s5@xyz": ({"c_temp2s5@x": 1, "c_temp2s5@y": -1, "c_temp2s5@z": 1}, 2.5e-5),  # bias ∝ (T − T̄)²
    "osc600@x": ({"c_sin600@x": 1, "c_cos600@x": 0.7}, 7e-5),  # a bias oscillating with a 10-minute period
    "ax.ay@z": ({"c_ax.ay@z": 1}, 3.5e-4),  # z output += c·A_x·A_y
    "prevax@x": ({"c_prevax@x": 1}, 7e-5),  # hysteresis: the previous pose's load on x shifts x
    "time2s500@z": ({"c_time2s500@z": 1}, 1e-4),  # a bias accelerating with time
    "ax.temp1s5@y": ({"c_ax.temp1s5@y": 1}, 1.2e-4),  # a misalignment changing with temperature
    "ax.ay.az@x": ({"c_ax.ay.az@x": 1}, 8e-4),  # a third-order product
    "ax.az2@z": ({"c_ax.az2@z": 1}, 6e-4),  # a third-order cross term
    "temp3s5@y": ({"c_temp3s5@y": 1}, 2e-5),  # bias ∝ (T − T̄)³
    "osc300@xyz": ({"c_sin300@x": 1, "c_cos300@y": 1, "c_sin300@z": -1}, 5e-5),  # every axis, a 5-minute period
}


def hidden(term: str | None, seed: int, size: float | None = None, scheme: str = "random:40"):
    """40 random poses at 10 µg with temperature set-points visited in a random order and times 30 s apart, and
    the effect ``term`` hidden (None: no effect; the same draws). As tests/test_discovery.py's ``hidden``: for an
    effect of temperature the rows are shuffled under increasing times, for one of time the temperatures are
    shuffled (so that T − T̄ and t − t0 are not one regressor); an effect of the previous pose keeps the order."""
    rng = np.random.default_rng(seed)
    truth = draw_truth("linear9", rng)
    effects = {}
    if term is not None:
        shape, default = EFFECTS[term]
        effects = {term: {k: v * (default if size is None else size) for k, v in shape.items()}}
    sim = simulate("linear9", truth, rng, scheme=scheme, noise_g=NOISE, effects=effects, temp=(20.0, 40.0),
                   times=True)
    data = sim.data
    t = TERMS[term] if term is not None else None
    if t is None or "t" in t.needs:
        data = dataclasses.replace(data, temp=rng.permutation(data.temp))
    elif t.feature.prev is None:
        data = dataclasses.replace(data.subset(rng.permutation(len(data))), t=data.t)
    return sim, data


def named(found: str, truth: str) -> bool:
    """The found term is the hidden one; a sinusoid's period within 10 % (the period is estimated)."""
    f, t = TERMS[found], TERMS[truth]
    if t.feature.period is not None:
        return (f.feature.period is not None and f.axes == t.axes
                and abs(f.feature.period / t.feature.period - 1.0) <= 0.1)
    return found == truth


@pytest.mark.slow
@pytest.mark.parametrize("term", list(EFFECTS))
def test_each_effect_outside_the_list_is_named_and_the_gap_closes(term):
    """20 seeds per effect: named by its formula (with nothing else) in at least 18, and in those the residual
    within 1.3 × what linear9 leaves on the same data without the effect."""
    got, exact, closed, bad = 0, 0, 0, []
    for seed in range(20):
        _, data = hidden(term, seed)
        _, clean = hidden(None, seed)
        rep = discover(data, noise_g=NOISE)
        no_effect = fit_model(get_model("linear9"), clean, 1.0).rms
        ok = any(named(s.kept, term) for s in rep.found)
        got += ok
        exact += ok and len(rep.added) == 1
        closed += ok and rep.final.rms <= 1.3 * no_effect
        if not ok:
            bad.append((seed, rep.added, round(rep.initial.rms * 1e6, 1), round(rep.final.rms * 1e6, 1)))
        if ok and seed == 0:
            assert rep.initial.rms >= 2.5 * NOISE and rep.verdict == EXPLAINED and rep.closes_gap
    print(f"{term}: named in {got} of 20 seeds (alone in {exact}), gap closed in {closed}; missed: {bad}")
    assert got >= 18 and exact >= 18 and closed >= 18, bad


@pytest.mark.slow
def test_without_an_effect_a_false_discovery_in_at_most_5_percent_of_seeds():
    """100 seeds of 40 poses with temperature and time (the whole dictionary on offer) and no effect: any term
    named (by the list or the dictionary) in at most 5 (measured: 2 of these 100, 4 of 200)."""
    false = []
    for seed in range(100):
        _, data = hidden(None, 5000 + seed)
        rep = discover(data, noise_g=NOISE)
        if rep.added or rep.partial:
            false.append((seed, rep.added, [s.term for s in rep.partial]))
    print(f"false discoveries: {len(false)} of 100: {false}")
    assert len(false) <= 5


def test_a_named_term_comes_with_its_formula_units_and_equivalents():
    _, data = hidden("ax.ay@z", 3)
    rep = discover(data, noise_g=NOISE)
    assert [s.kept for s in rep.found] == ["ax.ay@z"] and rep.verdict == EXPLAINED and rep.closes_gap
    step = rep.found[0]
    assert step.formula == "z output += c·A_x·A_y" and step.source == "dictionary"
    # the norm of static positions sees c·A_x·A_y·A_z whichever output carries the product
    assert sorted(step.equivalents) == ["ax.az@y", "ay.az@x"]
    assert step.parameters["c_ax.ay@z"] == pytest.approx(3.5e-4, abs=4 * step.stderr["c_ax.ay@z"])
    assert step.p_threshold == pytest.approx(rep.alpha / step.k_tested)
    d = rep.to_dict()
    assert d["found"][0]["term"] == "ax.ay@z" and d["closes_gap"] is True
    assert d["steps"][-1]["source"] == "dictionary" and d["steps"][-1]["formula"] == step.formula
    text = rep.summary()
    assert "found: z output += c·A_x·A_y [ax.ay@z]: closes the gap" in text
    assert "--model linear9+ax.ay@z" in text and "c_ax.ay@z" in text and "1/g" in text


def test_the_period_of_an_oscillation_and_the_periodogram():
    _, data = hidden("osc600@x", 1)
    rep = discover(data, noise_g=NOISE)
    per = rep.diagnostics_listed.get("periodicity")
    assert per.significant and abs(per.extra["period_s"] / 600 - 1) < 0.1 and per.extra["false_alarm"] < 1e-6
    pg = rep.diagnostics_listed.periodogram
    assert pg["n_independent"] == 19 and pg["powers"].shape == (4, len(pg["freqs_hz"]))
    found = rep.found[0]
    assert named(found.kept, "osc600@x") and TERMS[found.kept].params[0].startswith("c_sin")
    # once it is in, nothing periodic is left
    assert not rep.diagnostics.get("periodicity").significant


def test_only_the_right_diagnostic_is_significant():
    """Against the floor and against the residual that remains (diagnostics.test_columns): a large effect of the
    orientation leaves temperature, time, order as they are."""
    _, data = hidden("ax.ay.az@x", 2)
    rep = discover(data, noise_g=NOISE)
    sig = [d.name for d in rep.diagnostics_listed.significant]
    assert sig == ["orientation"], rep.diagnostics_listed.summary()
    assert rep.diagnostics.significant == []
    _, data = hidden("prevax@x", 2)
    sig = [d.name for d in discover(data, noise_g=NOISE).diagnostics_listed.significant]
    assert "order" in sig and "temperature" not in sig


def test_nothing_is_named_when_no_term_closes_the_gap():
    """Excess noise (30 µg more on every axis of every pose, three times the stated floor): in 10 seeds nothing is
    named, the verdict says something remains and that no term closes the gap, and a diagnostic is significant
    by chance in at most one (each is tested at α/k against the floor and against the residual left, so excess
    noise alone does not make them significant: measured 1 in 10 here, orientation at p = 2.4e-4)."""
    chance = 0
    for seed in range(10):
        _, data = hidden(None, seed)
        rng = np.random.default_rng(100 + seed)
        data = dataclasses.replace(data, N=data.N + 30e-6 * rng.standard_normal(data.N.shape))
        rep = discover(data, noise_g=NOISE)
        assert rep.added == [] and rep.found == [] and rep.verdict == REMAINS
        assert "no term of the list or the dictionary closes the gap" in rep.summary()
        chance += bool(rep.diagnostics.significant)
    assert chance <= 1


def test_a_term_that_leaves_the_gap_open_is_not_named():
    """The product is there and significant, but 30 µg of excess noise keeps the χ² test failing: the term is
    reported as the nearest, not named, and the final model is the list's."""
    partial = 0
    for seed in range(4):
        _, data = hidden("ax.ay@z", seed, size=1e-3)
        rng = np.random.default_rng(200 + seed)
        data = dataclasses.replace(data, N=data.N + 30e-6 * rng.standard_normal(data.N.shape))
        rep = discover(data, noise_g=NOISE)
        assert rep.found == [] and rep.verdict == REMAINS and "ax.ay@z" not in rep.final_model.terms
        if rep.partial:
            partial += 1
            assert rep.partial[0].term == "ax.ay@z" and rep.closes_gap is False and rep.gap_p < rep.alpha
            assert "the nearest, ax.ay@z" in rep.summary()
    assert partial == 4


def test_without_noise_information_replicates_or_what_to_record():
    # the 24-position scheme visits its six ±axis poses twice: their scatter is the floor
    _, data = hidden("ax.ay@z", 0, scheme="24")
    rep = discover(data)  # no noise_g, no n or sx, sy, sz
    assert rep.floor.kind == "replicates" and rep.floor.pure_dof == 6 and rep.lack_of_fit is not None
    # random poses, no noise information: the floor is unknown and the report says what to record
    _, data = hidden("ax.ay@z", 0)
    rep = discover(data)
    assert rep.floor.kind is None and rep.verdict == UNKNOWN
    assert rep.to_dict()["floor"]["what_to_record"].startswith("record the poses from a raw recording")
    # a term is still named by the same F-test, said to be unverified against a floor
    assert [s.kept for s in rep.found] == ["ax.ay@z"] and rep.closes_gap is None
    assert "without a floor whether it closes the gap is unknown" in rep.summary()


def test_the_list_is_searched_first_and_a_list_term_is_not_exchanged_for_a_feature():
    """Today's candidates are named as today (tests/test_discovery.py); the dictionary adds nothing after a list
    term, and a list term whose every output is significant is never exchanged for a feature (the quadratic
    case of 36 positions where scale_asymmetry follows it spuriously)."""
    from test_discovery import effect
    from test_discovery import hidden as list_hidden

    _, data = list_hidden({"quadratic": effect("quadratic", 1.5e-4)}, "36", 0)
    rep = discover(data, noise_g=NOISE)
    assert rep.added[:1] == ["quadratic"] and rep.found == []
    assert not any(r.kind == "replaced" for r in rep.removed)


def test_a_three_output_term_is_narrowed_to_its_one_output():
    """Seed 17 of the time power: the list adds bias_drift and temperature_bias, exchanges take both out, the
    dictionary adds the quadratic time feature on all three outputs, and it is narrowed to z (the other two
    outputs' coefficients not significant together)."""
    _, data = hidden("time2s500@z", 17)
    rep = discover(data, noise_g=NOISE)
    assert [(s.term, s.kept) for s in rep.found] == [("time2s500@xyz", "time2s500@z")]
    narrowed = [r for r in rep.removed if r.kind == "narrowed"]
    assert [(r.term, r.after) for r in narrowed] == [("time2s500@xyz", "time2s500@z")] and narrowed[0].p_value >= 0.01
    assert {r.term for r in rep.removed if r.kind == "replaced"} == {"bias_drift", "temperature_bias"}
    assert rep.final_model.terms == ("scale", "bias", "misalignment", "time2s500@z")
    assert "narrowed time2s500@xyz to time2s500@z" in rep.summary()


def test_the_diagnostics_figure(tmp_path):
    _, data = hidden("osc600@x", 1)
    rep = discover(data, noise_g=NOISE)
    fig = rep.plot_diagnostics(tmp_path / "d.png")
    assert (tmp_path / "d.png").stat().st_size > 30_000
    titles = [a.get_title() for a in fig.axes if a.get_title()]
    # the list's residuals and the final model's: the oscillation significant after the list, gone after
    assert any(t.startswith("periodicity 6") and "(sig.) → " in t and not t.endswith("(sig.)") for t in titles)
    assert any(t.startswith("orientation: p = ") and " → " in t for t in titles)
    assert any(t.startswith("Lomb–Scargle after the list (19 indep") for t in titles)
    assert "duration: not tested" in titles and titles[-1] == "per position: explained down to noise"


def test_the_duration_diagnostic_sees_a_settling_bias():
    """Poses of 2 to 20 s (the samples averaged, n) with bias_x settling as 1/duration (60 µg·(d̄/d − 1)): the
    duration diagnostic is significant after the list, the others are not; without the effect it is not."""
    for effect, expect in ((60e-6, True), (0.0, False)):
        _, data = hidden(None, 7)
        rng = np.random.default_rng(70)
        n = rng.integers(200, 2000, len(data)).astype(float)
        N = data.N.copy()
        N[:, 0] += effect * (np.median(n) / n - 1.0)
        data = dataclasses.replace(data, N=N, n_samples=n)
        rep = discover(data, noise_g=NOISE)
        sig = [d.name for d in rep.diagnostics_listed.significant]
        assert (sig == ["duration"]) if expect else sig == [], rep.diagnostics_listed.summary()
