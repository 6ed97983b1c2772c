"""The structure registry: a structure added from outside the package works end to end.

A toy FIR structure  y = B(q) u + e  (orders [nb nk]) is registered here, in the test
file alone, and then estimated, run through the study (Hydra config schema generated
from the registry, one sweep into a temporary store) and ranked.
"""

from __future__ import annotations

import numpy as np
import pytest

from maglev import IOData
from maglev.estimation import estimate
from maglev.lab.signals import random_binary
from maglev.structures import PolySpec, Structure, get, names, register, unregister

FIR = Structure("fir", ("nb", "nk"), "y = B(q) u + e", "A finite impulse response: B alone, least squares.")


@pytest.fixture
def fir():
    """FIR registered for one test (library and study), then removed again."""
    from hydra.core.config_store import ConfigStore

    from maglev.study import schema

    register(FIR)
    ConfigStore.instance().store(group="structure", name="fir", node=schema.register_structure("fir"))
    yield FIR
    unregister("fir")
    schema.STRUCTURE_SCHEMAS.pop("fir", None)
    for key in ("fir.yaml", "fir_schema.yaml"):
        ConfigStore.instance().repo["structure"].pop(key, None)


def test_built_ins_are_registered_in_matlab_order():
    assert names()[:5] == ("arx", "armax", "oe", "bj", "pem")
    assert get("bj").orders == ("nb", "nc", "nd", "nf", "nk") and not get("bj").least_squares
    assert get("arx").least_squares and get("arx").label == "[na nb nk]"
    with pytest.raises(ValueError, match="unknown structure 'fir'; expected one of"):
        get("fir")


def test_a_structure_must_name_real_orders_and_cannot_be_redefined():
    with pytest.raises(ValueError, match="nk last"):
        Structure("bad", ("nb", "nx", "nk"), "", "")
    with pytest.raises(ValueError, match="already registered"):
        register(Structure("arx", ("nb", "nk"), "", ""))


def test_toy_structure_is_estimated_by_least_squares(fir):
    b_true = np.array([0.0, 0.0, 0.5, 0.3, -0.2])
    u = random_binary(3000, 0.3, -1.0, 1.0, seed=2)
    y = np.convolve(u, b_true)[: u.size] + 0.01 * np.random.default_rng(3).standard_normal(u.size)
    m = estimate(IOData(u, y, 0.01), "fir", [3, 2], initial_condition="zero")
    assert m.structure == "fir" and m.orders == (3, 2) and m.label == "fir[3 2]"
    assert np.allclose(m.B, b_true, atol=0.01) and m.A.tolist() == [1.0] and m.F.tolist() == [1.0]
    assert m.report.method == "least squares"
    with pytest.raises(ValueError, match="fir: has no na"):
        PolySpec("fir", na=1, nb=2)
    with pytest.raises(ValueError, match="takes no options"):
        estimate(IOData(u, y, 0.01), "fir", [3, 2], max_iterations=5)


def test_toy_structure_runs_through_a_sweep_and_the_ranking(fir, migrated_store):
    from tests.study.harness import LEAN, TINY, all_runs, launch

    from maglev.study.ranking import compute, log_ranking
    from maglev.study.store import load_sweep

    launch(migrated_store, "dataset=uniform_narrow,binary_a025", "structure=fir,arx", "structure.order=3", *TINY, *LEAN)
    _, _, runs = all_runs(migrated_store)
    fir_runs = [r for r in runs if r.data.tags.get("structure") == "fir"]
    assert len(fir_runs) == 2 and all(r.info.status == "FINISHED" for r in fir_runs)
    assert {r.data.tags["orders"] for r in fir_runs} == {"[3 1]"}  # nb from structure.order, nk the schema default
    assert all(r.data.metrics["n_params"] == 3 for r in fir_runs)
    ranking = compute(load_sweep(f"sqlite:///{migrated_store}/mlflow.db", "maglev"))
    assert set(ranking.table["structure"]) == {"fir", "arx"} and len(ranking.table) == 4
    assert ranking.structure in ("fir", "arx")  # both have binary- and uniform-input runs
    assert log_ranking(ranking)
