"""Tests of maglev.sim.checks: each declared check's error is its relative error over its tolerance, a check
the measured numbers lack is left out, and the verdicts and their line read the same list.

Built on hand-made numbers (no records needed); the acceptance test that runs every check on the default plant
against the real records is ``test_the_default_plant_meets_every_declared_check`` in test_sim_vs_real.py."""

import math
from types import SimpleNamespace

import pytest

from maglev.sim import checks


def _measured(**changes) -> SimpleNamespace:
    """Numbers a comparison could hold, every check within its tolerance, some at it."""
    values = dict(
        static_rms=0.009, static_tolerance=0.01, rise_real=10.0, rise_sim=12.5, alpha_real=0.25, alpha_sim=0.25,
        modes={rec: ((90.0, 0.2), (99.0, 0.18)) for rec in checks.POLE_RECORDS},
        white_noise_mode=((200.0, 0.4), (200.0, 0.4)),
        stds={**{rec: (1.0, 1.25 if i % 2 else 0.8) for i, rec in enumerate(checks.STD_RECORDS)},
              "binary_signal_2": (1.0, 1.2), "white_noise_4": (1.0, 1.0)},
        armax_pairs=(((74.0, 0.26), (218.0, 0.11)), ((74.0 * 1.06, 0.26 * 0.88), (218.0, 0.11))),
        frf={rec: SimpleNamespace(max_db=3.0) for rec in checks.FRF_RECORDS})
    values.update(changes)
    return SimpleNamespace(**values)


def test_every_check_has_a_unique_name_a_record_a_tolerance_and_a_reason():
    names = [c.name for c in checks.CHECKS]
    assert len(names) == len(set(names)) == 3 + 5 + 7 + 1 + 2 + 3
    assert all(c.what and c.record and c.tolerance and c.why for c in checks.CHECKS)
    assert {c.name for c in checks.CHECKS if not c.scored} == {"static curve", "alpha*"}


def test_errors_are_relative_errors_over_the_tolerances_and_at_the_tolerance_a_check_is_within():
    m = _measured()
    errors = checks.errors(m)
    assert errors["static curve"] == {"": pytest.approx(0.9)}
    assert errors["rise time"] == {"": pytest.approx(1.0)}
    assert errors["mode binary_signal_3"] == {"wn": pytest.approx(0.5), "zeta": pytest.approx(0.5)}
    assert errors["std white_noise_1"] == {"": pytest.approx(1.0)}  # 1.25 x, the band's edge
    assert errors["std binary_signal_1"] == {"": pytest.approx(1.0)}  # 0.8 x
    assert errors["std ratio"] == {"": pytest.approx(0.2 / checks.RATIO_TOLERANCE)}
    assert errors["ARMAX slow mode"] == {"wn": pytest.approx(0.06 / 0.15), "zeta": pytest.approx(0.12 / 0.30)}
    assert errors["FRF white_noise_4"] == {"": 1.0}
    assert all(checks.verdicts(m).values())
    assert checks.verdict_line(m) == "Checks within their tolerances: 21 of 21"


def test_a_check_beyond_its_tolerance_or_missing_in_the_simulation_is_not_within_and_named():
    m = _measured(rise_sim=12.6, alpha_sim=0.5, armax_pairs=(((74.0, 0.26), (218.0, 0.11)), ((74.0, 0.26), None)),
                  frf={**_measured().frf, "binary_signal_3": SimpleNamespace(max_db=math.nan)})
    v = checks.verdicts(m)
    assert [name for name, ok in v.items() if not ok] == ["rise time", "alpha*", "ARMAX fast mode",
                                                          "FRF binary_signal_3"]
    assert math.isnan(checks.errors(m)["ARMAX fast mode"]["wn"])  # the simulation lacks the mode
    assert checks.verdict_line(m) == ("Checks within their tolerances: 17 of 21; not within: rise time, alpha*, "
                                      "ARMAX fast mode, FRF binary_signal_3")


def test_checks_whose_records_the_numbers_lack_are_left_out():
    m = _measured(modes={"binary_signal_3": ((90.0, 0.2), (90.0, 0.2))}, white_noise_mode=None, stds=None,
                  armax_pairs=None, frf=None)
    assert list(checks.verdicts(m)) == ["static curve", "rise time", "alpha*", "mode binary_signal_3"]
    assert list(checks.errors(m, scored_only=True)) == ["rise time", "mode binary_signal_3"]
