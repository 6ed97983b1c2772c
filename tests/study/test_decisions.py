"""The lab's decisions on the real 2022 records (skip without ../shared), on the simulated lab set, and in the
study's configs."""

from __future__ import annotations

import pytest

from maglev.refdata import DESIGN_ALPHA, RECORDS
from maglev.study import schema  # noqa: F401  (registers the resolvers)

from .harness import CONF


def test_every_2022_record_has_a_dataset_config():
    configs = {p.stem for p in (CONF / "dataset").glob("real_*.yaml")}
    assert {f"real_{r}" for r in RECORDS if r != "working_region"} <= configs


@pytest.fixture
def real_decisions(refdata):
    from maglev.study.decisions import assessed_2022, real_region, records_2022

    return real_region(str(refdata), None), assessed_2022(str(refdata), None), records_2022(str(refdata), None)


def test_real_working_region_ends_below_the_plateau(real_decisions):
    wr, _, _ = real_decisions
    assert (wr.u_min, wr.u_max) == (1.5, 3.5)
    assert wr.y_bar[wr.hi] < wr.plateau_level - wr.plateau_margin * (wr.y_bar.max() - wr.y_bar.min())


def test_real_records_chosen_keep_their_output_on_the_static_curve(real_decisions):
    _, assessed, dec = real_decisions
    by = {a.name: a for a in assessed}
    chosen = [n for names in dec.choice.values() for n in names]
    assert len(dec.choice["uniform"]) == 2 and len(dec.choice["binary"]) == 1
    assert all(by[n].output_outside <= 0.02 and by[n].input_outside <= 0.02 and not by[n].refusals for n in chosen)
    # the issue's counter-examples: binary_signal_2's output leaves the curve; white_noise_4 covers the whole
    # region but a fifth of its input lies beyond it (1.5-4.0 A), so the rule refuses it
    assert by["real_binary_signal_2"].refusals and "real_binary_signal_2" not in chosen
    assert by["real_white_noise_4"].input_outside > 0.1 and "real_white_noise_4" not in chosen
    # every uniform record the rule passes over is refused or scores lower than the ones chosen
    for a in assessed:
        if a.input_class == "uniform" and a.name not in chosen:
            assert a.refusals or a.score < min(by[n].score for n in dec.choice["uniform"]), a.name


def test_real_binary_records_alpha_within_002_of_design(real_decisions):
    _, assessed, _ = real_decisions
    for a in assessed:
        if a.input_class == "binary":
            assert a.alpha == pytest.approx(DESIGN_ALPHA[a.name.removeprefix("real_")], abs=0.02), a.name


def test_real_choice_configs_resolve_to_the_rule_and_meet_the_length_or_say_why(refdata, monkeypatch):
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from maglev.study.config import plain_config
    from maglev.study.decisions import length_rows, records_2022
    from maglev.lab.records import length_decision

    monkeypatch.setenv("MAGLEV_REFDATA", str(refdata))
    names = []
    with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):
        for stem in ("real_choice_uniform_1", "real_choice_uniform_2", "real_choice_binary_1"):
            c = compose("config", overrides=[f"dataset={stem}", "lab=real"])
            names.append(plain_config(OmegaConf.masked_copy(c, [k for k in c if k != "hydra"]))["dataset"])
    rule = records_2022(str(refdata), "el2820_maglev_2022/working_region.mat").choice
    assert [d["name"] for d in names] == rule["uniform"] + rule["binary"]
    dec = length_decision(length_rows(names, str(refdata)))
    for name, part in dec.choice.items():
        met = part["est_s"] >= 10 and part["val_s"] >= 7
        assert met or any(c.startswith(f"{name}: ") and "too short" in c for c in dec.cautions)
    with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):  # an override forces the trim
        c = compose("config", overrides=["dataset=real_white_noise_4", "dataset.preprocess.trim=2000"])
    forced = plain_config(OmegaConf.masked_copy(c, [k for k in c if k != "hydra"]))["dataset"]
    assert forced["preprocess"]["trim"] == 2000
    d = length_decision(length_rows([forced], str(refdata)))
    assert d.forced and d.reasons[0].startswith("The trim of real_white_noise_4 is set by the config")
    assert not length_decision(length_rows(names, str(refdata))).forced


def _sim_sweep(*datasets: str) -> list:
    """The dataset configs named ``datasets``, then the simulated staircase's working region."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from maglev.lab.working_region import working_region
    from maglev.sim.plant import DEFAULT_PLANT
    from maglev.study.config import plain_config
    from maglev.study.lab import staircase

    out = []
    with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):
        for name in datasets:
            c = compose("config", overrides=[f"dataset={name}"])
            out.append(plain_config(OmegaConf.masked_copy(c, [k for k in c if k != "hydra"]))["dataset"])
    stairs = staircase({"staircase_file": None}, "", DEFAULT_PLANT)
    stairs = stairs.segment(0, stairs.N - stairs.N % 21)
    return [*out, working_region(stairs.u, stairs.y, 21, 50.0)]


def test_the_simulated_sweeps_datasets_are_the_record_rules_choice_from_the_simulated_lab_set():
    """conf/sweep/lab.yaml's datasets are what the records rule chooses from the simulated lab set on the default
    plant, by the rule's reasons: inside the working region, centred at u*, the output on the static curve, the
    widest such uniform records and the binary record at α*; the record beyond the region and the wider α = 0.25
    binary records are refused.  A ``dataset=`` override is reported forced."""
    from maglev.lab.records import verdicts
    from maglev.study.decisions import SIM_RECORDS, sim_records

    *datasets, other, wr = _sim_sweep("uniform_narrow", "uniform_wide", "binary_a025", "binary_a05")
    assert (wr.u_min, wr.u_max) == (1.5, 3.5)
    dec = sim_records(datasets, wr, "")
    assert not dec.forced and dec.choice == {"uniform": ["uniform_wide", "uniform_narrow"], "binary": ["binary_a025"]}
    rows = {r["record"]: r for r in dec.evidence}
    assert len(rows) == len(SIM_RECORDS)
    for name in ("uniform_wide", "uniform_narrow", "binary_a025"):
        r = rows[name]
        assert r["u outside region"] == 0 and r["y outside curve"] <= 0.02 and r["offset / width"] < 0.01, name
        assert r["usable (s)"] >= 17, name
    assert rows["uniform_wide"]["covers region"] > 0.99
    assert rows["binary_a025"]["α"] == pytest.approx(0.25, abs=0.02)
    verdict = verdicts(dec)
    assert verdict["sim_uniform_1.5-4"].startswith("refused: ") and "of its input outside the working region" in \
        verdict["sim_uniform_1.5-4"]
    assert all(verdict[n].startswith("refused: ") for n in ("sim_binary_1.5-3.5_a0.25", "sim_binary_1.75-3.25_a0.25"))
    # the narrower uniform records and binary records at other α lose on their numbers
    assert verdict["sim_uniform_1.5-3"].startswith("not chosen: score")
    assert verdict["sim_binary_1.5-3.5_a0.5"].startswith("not chosen: its α")
    forced = sim_records([datasets[0], other], wr, "")
    assert forced.forced and forced.choice["forced"] == ["binary_a05", "uniform_narrow"]
    # the rule's choice is the same records; those not in the sweep carry their names in the simulated set
    assert forced.choice["rule"] == {"uniform": ["sim_uniform_1.5-3.5", "uniform_narrow"],
                                     "binary": ["sim_binary_2-3_a0.25"]}
    assert forced.reasons[1].startswith("The config forces")
    assert any(c.startswith("binary_a05 is forced by the config although the rule refuses it") for c in forced.cautions)
    assert verdicts(forced)["binary_a05"].endswith("; used: forced by the config")
