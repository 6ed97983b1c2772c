"""The record rules on constructed records with known answers: start transient, split, α, choice."""

from __future__ import annotations

import numpy as np
import pytest

from maglev.lab.records import (alpha_decision, assess, choose_records, length_decision, length_split,
                                start_transient, switching_rate, verdicts)
from maglev.lab.signals import random_binary, uniform_noise

TS = 0.001
REGION = (1.5, 3.5)
CURVE = (7.9, 9.3)


def _noise(n, level, sd=0.01, seed=0):
    return level + sd * np.random.default_rng(seed).standard_normal(n)


def test_a_level_shift_at_the_start_is_trimmed_where_it_settles():
    y = _noise(20000, 8.26)
    y[:1500] -= 0.27  # the first 1.5 s at another level, as white_noise_2 starts
    tr = start_transient(y, TS)
    assert tr.seconds == pytest.approx(1.5) and tr.outside == tuple(range(6))


def test_a_lift_off_spike_costs_one_block_and_a_later_stray_block_none():
    y = _noise(20000, 8.6)
    y[:40] += 0.7  # a 40 ms spike
    y[8000:8250] += 0.3  # one stray block at 8 s: not a start transient
    assert start_transient(y, TS).seconds == pytest.approx(0.25)
    assert start_transient(_noise(20000, 8.6, seed=3), TS).samples == 0


@pytest.mark.parametrize(("seconds", "split", "met"), [(24.0, 0.5, True), (19.75, 10 / 19.75, True),
                                                       (15.25, 10 / 17, False)])
def test_the_split_meets_10_s_and_7_s_when_the_record_allows(seconds, split, met):
    assert length_split(int(round(seconds / TS)), TS) == (pytest.approx(split), met)


@pytest.mark.parametrize("alpha", [0.25, 0.5, 0.75, 1.0])
def test_alpha_is_the_switching_rate_per_recorded_sample(alpha):
    u = random_binary(20000, alpha, 1.5, 3.5, seed=1)
    assert switching_rate(u) == pytest.approx(alpha, abs=0.02)
    assert switching_rate(u[::2]) != pytest.approx(alpha, abs=0.02) or alpha == 0.5  # not on a decimated axis


def test_alpha_decision_sentence_flips_when_the_rate_leaves_the_tolerance():
    good = alpha_decision([{"dataset": "b", "alpha": 0.251, "design": 0.25, "samples": 20000}])
    bad = alpha_decision([{"dataset": "b", "alpha": 0.30, "design": 0.25, "samples": 20000}])
    assert "within 0.02" in good.reasons[0] and not good.cautions
    assert "off by 0.050" in bad.cautions[0] and not bad.reasons


def _record(name, cls, u, y):
    return assess(name, cls, u, y, TS, REGION, CURVE)


def test_a_record_whose_output_leaves_the_curve_is_refused_even_with_the_best_input():
    n = 20000
    u_wide = uniform_noise(n, 1.5, 3.5, seed=1)
    u_narrow = uniform_noise(n, 2.2, 2.8, seed=2)
    inside = _noise(n, 8.6, 0.1)
    leaving = inside.copy()
    leaving[::4] = 10.5  # 25 % of the output above the curve's top
    a = [_record("wide_leaves", "uniform", u_wide, leaving), _record("wide", "uniform", u_wide, inside),
         _record("narrow", "uniform", u_narrow, inside), _record("bin", "binary", random_binary(n, 0.25, 1.5, 3.5, 3),
                                                                 inside)]
    d = choose_records(a, alpha_star=0.25, wanted={"uniform": 2, "binary": 1})
    assert d.choice == {"uniform": ["wide", "narrow"], "binary": ["bin"]} and not d.forced
    verdict = verdicts(d)
    assert verdict["wide_leaves"].startswith("refused: 25.0 % of its output") and verdict["wide"] == "chosen (uniform #1)"
    assert d.reasons == ["Of 4 records, 3 chosen, 1 refused and 0 not chosen for a lower score or an α farther from "
                         "α*: each record's verdict is its row of the table."]
    # the same records with the output back inside: the wide record wins on its score, the narrow one loses
    b = [_record("wide_leaves", "uniform", u_wide, inside)] + a[1:]
    flipped = choose_records(b, alpha_star=0.25)
    assert flipped.choice["uniform"][0] in {"wide_leaves", "wide"} and "narrow" not in flipped.choice["uniform"]
    assert verdicts(flipped)["narrow"].startswith("not chosen: score")
    assert flipped.reasons[0].startswith("Of 4 records, 3 chosen, 0 refused and 1 not chosen")
    forced = choose_records(a, alpha_star=0.25, forced=["wide_leaves", "narrow", "bin"])
    assert verdicts(forced)["wide_leaves"].endswith("; used: forced by the config")
    assert forced.forced and forced.choice["forced"] == ["bin", "narrow", "wide_leaves"]
    assert any("forced by the config although the rule refuses it" in c for c in forced.cautions)


def test_length_decision_cautions_only_when_the_minimum_is_not_met():
    ok = {"dataset": "a", "transient_s": 0.25, "trim_s": 0.25, "split": 0.506, "est_s": 10.0, "val_s": 9.75}
    short = {**ok, "dataset": "b", "est_s": 8.97, "val_s": 6.28}
    assert length_decision([ok]).cautions == []
    d = length_decision([ok, short])
    assert len(d.cautions) == 1 and d.cautions[0].startswith("b: 8.97 s estimation")
    assert d.reasons == ["1 of the 2 records hold the lab's 10 s of estimation and 7 s of validation data after their "
                         "trim; b does not (a caution below)."]
    assert length_decision([ok]).reasons[-1] == ("Every record holds the lab's 10 s of estimation and 7 s of "
                                                 "validation data after its trim.")


def test_a_trim_set_by_the_config_is_kept_when_it_is_longer_than_the_detected_transient():
    """The simulated datasets trim their config's 2 s, longer than the detected transient: the decision says the
    trim is kept and why; a trim shorter than the transient is named as such, with a caution."""
    longer = {"dataset": "sim", "transient_s": 0.5, "trim_s": 2.0, "split": 0.5, "est_s": 11.0, "val_s": 11.0}
    d = length_decision([longer])
    assert d.forced and d.cautions == []
    assert d.reasons[0].startswith("The trim of sim is set by the config (dataset.preprocess.trim), not the detected "
                                   "start transient beside it, and kept: it is longer than the transient")
    shorter = {**longer, "trim_s": 0.25}
    d = length_decision([shorter])
    assert d.forced and "kept" not in d.reasons[0] and "shorter than the detected start transient" in d.reasons[0]
    assert d.cautions == ["sim: the trim 0.25 s is shorter than the detected start transient 0.50 s."]
    assert not length_decision([{**longer, "trim_s": 0.5}]).forced  # the rule's own trim


def test_a_record_whose_input_leaves_the_region_is_refused_however_much_of_it_covers():
    """white_noise_4's case: U(1.5, 4.0) A covers the whole region [1.5, 3.5] A and its output stays on the curve,
    but 20 % of its input lies beyond the region's upper bound (lab §3.1: the input never exceeds the region's
    boundary), so it loses to narrower records inside the region; with the excursion within the rule's 2 % it
    wins again on its coverage."""
    n = 20000
    on_curve = _noise(n, 8.6, 0.1)
    beyond = uniform_noise(n, 1.5, 4.0, seed=1)
    inside = [_record("lower", "uniform", uniform_noise(n, 1.5, 3.0, seed=2), on_curve),
              _record("narrow", "uniform", uniform_noise(n, 1.75, 2.5, seed=3), on_curve)]
    wide = _record("beyond", "uniform", beyond, on_curve)
    assert wide.input_outside == pytest.approx(0.2, abs=0.01) and wide.output_outside == 0.0
    assert wide.score > max(a.score for a in inside)  # the score alone would pick it
    d = choose_records([wide, *inside], wanted={"uniform": 2})
    assert d.choice == {"uniform": ["lower", "narrow"]}
    assert verdicts(d)["beyond"].startswith("refused: 20.") and "of its input outside the working region" in \
        verdicts(d)["beyond"]
    # a brief excursion (1 % of the samples just above 3.5 A) stays within the rule: the wide record wins
    brief = np.clip(beyond, 1.5, 3.5)
    brief[::100] = 3.6
    flipped = choose_records([_record("beyond", "uniform", brief, on_curve), *inside], wanted={"uniform": 2})
    assert flipped.choice == {"uniform": ["beyond", "lower"]}
    assert verdicts(flipped)["narrow"] == f"not chosen: score below lower's {flipped.evidence[1]['score']:.3f}"


def test_a_chosen_record_shorter_than_the_labs_minimum_says_why_it_is_chosen_all_the_same():
    """white_noise_1's case: 15.25 s after its start transient (the lab wants 10 s + 7 s), chosen because only two
    uniform records pass the rule; with a third passing record scoring below it, the caution gives that score."""
    from maglev.lab.records import RecordAssessment

    def rec(name, coverage, usable_s):
        return RecordAssessment(name, "uniform", 1.5, 3.0, 2.25, None, 4.75, usable_s, coverage, 0.125, 0.0, 0.0,
                                max(0.0, 17.0 - usable_s) / 17.0, True)

    short, other = rec("short", 0.75, 15.25), rec("other", 0.375, 18.5)
    d = choose_records([short, other], wanted={"uniform": 2})
    assert d.cautions == ["short: 15.25 s after its 4.75 s start transient, less than the lab's 10 s + 7 s. It is chosen "
                          "all the same: only 2 uniform record(s) pass the rule, 2 wanted."]
    third = rec("third", 0.25, 18.5)
    d = choose_records([short, other, third], wanted={"uniform": 2})
    assert d.cautions[0].endswith(f"It is chosen all the same: its score, the shortfall counted, is above third's "
                                  f"{third.score:.3f}.")
