"""Order and delay selection: arxstruc, selstruc, delayest."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from maglev.data import IOData
from maglev.polynomials import filt
from maglev.estimation.selection import arxstruc, delayest, selstruc

A2 = np.array([1.0, -1.5, 0.7])


def _arx_data(nk: int, N: int, seed: int) -> IOData:
    """ARX  A y = q^-nk (1 + 0.5 q^-1) u + e  with white input."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    B = np.r_[np.zeros(nk), 1.0, 0.5]
    y = filt(B, A2, u) + filt(np.ones(1), A2, 0.2 * rng.standard_normal(N))
    return IOData(u, y, 0.01)


@pytest.mark.parametrize("criterion", ["aic", "mdl"])
def test_arxstruc_selstruc_pick_the_true_orders(criterion):
    est, val = _arx_data(nk=3, N=4000, seed=0).split(0.5)
    table = arxstruc(est, val, range(1, 6), range(1, 6), range(1, 6))
    assert len(table) == 125
    assert selstruc(table, criterion) == (2, 2, 3)


def test_arxstruc_table_contents():
    est, val = _arx_data(nk=1, N=2000, seed=1).split(0.5)
    table = arxstruc(est, val, [1, 2], 2, [0, 1, 2])
    assert list(table.columns) == ["na", "nb", "nk", "loss", "n_params", "n_estimation"]
    assert (table["n_params"] == table["na"] + table["nb"]).all()
    assert (table["n_estimation"] == est.N).all()
    loss = table.set_index(["na", "nb", "nk"])["loss"]
    # the true structure explains the data down to the noise (variance 0.04); wrong delays do not
    assert loss[(2, 2, 1)] == pytest.approx(0.04, rel=0.15)
    assert loss[(2, 2, 0)] > 2 * loss[(2, 2, 1)]
    assert loss[(1, 2, 1)] > 2 * loss[(2, 2, 1)]


def test_selstruc_criteria_on_a_hand_made_table():
    table = pd.DataFrame(
        {"na": [1, 2], "nb": [1, 2], "nk": [1, 1], "loss": [1.0, 0.95], "n_params": [2, 4],
         "n_estimation": [100, 100]}
    )
    # AIC: 1.0·1.04 = 1.04 vs 0.95·1.08 = 1.026;  MDL: 1.0·(1 + 2 ln100/100) = 1.092 vs 0.95·1.184 = 1.125
    assert selstruc(table, "aic") == (2, 2, 1)
    assert selstruc(table, "mdl") == (1, 1, 1)
    assert selstruc(table, 0) == (2, 2, 1)
    assert selstruc(table, 10.0) == (1, 1, 1)  # 1.0·1.2 = 1.2 < 0.95·1.4 = 1.33


def test_delayest_finds_a_long_delay():
    data = _arx_data(nk=8, N=3000, seed=2)
    assert delayest(data, na=2, nb=2, nk_min=0, nk_max=12) == 8
    assert delayest(data, nk_min=5, nk_max=10) == 8


def test_selection_rejects_bad_arguments():
    est, val = _arx_data(nk=1, N=400, seed=3).split(0.5)
    with pytest.raises(ValueError, match="na_range"):
        arxstruc(est, val, [-1, 2], 2, 1)
    with pytest.raises(ValueError, match="nk_range"):
        arxstruc(est, val, 2, 2, [])
    with pytest.raises(ValueError, match="Ts"):
        arxstruc(est, IOData(val.u, val.y, 1.0), 2, 2, 1)
    with pytest.raises(ValueError, match="samples"):
        arxstruc(est, val, 2, 2, 195)
    table = arxstruc(est, val, 2, 2, 1)
    with pytest.raises(ValueError, match="criterion"):
        selstruc(table, "bic")
    with pytest.raises(ValueError, match="criterion"):
        selstruc(table, -1.0)
    with pytest.raises(ValueError, match="table"):
        selstruc(pd.DataFrame({"loss": [1.0]}))
    with pytest.raises(ValueError, match="nk_max"):
        delayest(est, nk_min=5, nk_max=2)
    with pytest.raises(ValueError, match="nb"):
        delayest(est, nb=0)
