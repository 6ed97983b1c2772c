"""Inputs at the library's edges that were used silently or refused with an unclear message: each is
now refused in one line naming the argument and what was expected."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.io import savemat

from maglev import IOData, PolyModel
from maglev.estimation import estimate
from maglev.validation import compare

from .systems import simulate, true_model


@pytest.fixture(scope="module")
def data() -> IOData:
    return simulate("oe", 500, seed=1)


def refused(needle: str):
    """pytest.raises for a ValueError whose one-line message contains ``needle``."""
    return pytest.raises(ValueError, match=re.escape(needle))


def test_a_masked_arrays_masked_values_are_not_used_as_data(data):
    u = np.ma.masked_array(data.u, mask=np.arange(data.N) == 3)
    with refused("input u is a masked array with 1 masked value(s), first at index 3; expected plain numbers"):
        IOData(u, data.y, data.Ts)
    np.testing.assert_array_equal(IOData(np.ma.masked_array(data.u), data.y, data.Ts).u, data.u)  # none masked


def test_a_bool_is_no_decimation_factor_nor_sampling_period(data):
    with refused("oe-seed1: decimation factor must be a positive integer, got True"):
        data.decimate(True)
    with refused("IOData: Ts must be a positive number of seconds, got True"):
        IOData(data.u, data.y, Ts=True)


@pytest.mark.parametrize("Ts, kind", [(True, "logical (1)"), ("0.001", "char ('0.001')")])
def test_a_mat_files_logical_or_text_ts_is_no_sampling_period(tmp_path, data, Ts, kind):
    """A logical ``Ts = true`` was read as 1 s (scipy loads it as uint8), although IOData refuses a bool."""
    path = tmp_path / "rec.mat"
    savemat(path, {"u": data.u, "y": data.y, "Ts": Ts})
    with refused(f"rec.mat: variable 'Ts' is {kind}; expected the sampling period in seconds as a number"):
        IOData.from_mat(path)
    savemat(path, {"u": data.u, "y": data.y, "Ts": 0.001})
    assert IOData.from_mat(path).Ts == 0.001


@pytest.mark.parametrize("reader", ["from_mat", "from_csv"])
def test_a_path_given_as_an_int_is_named(reader):
    with refused(f"IOData.{reader}: path must be a file path (str or pathlib.Path), got 5"):
        getattr(IOData, reader)(5)


def test_predict_refuses_data_of_another_sampling_period(data):
    m = true_model("oe")
    other = IOData(data.u, data.y, 2e-3, name="slow")
    with refused("predict: data slow has Ts = 0.002 s but oe[2 2 2] has Ts = 0.001 s; expected the same"):
        m.predict(other, 1)


@pytest.mark.parametrize("call, needle", [
    (lambda d: estimate(d, "oe", None), "oe takes orders [nb nf nk] (a list of 3 integers), got None"),
    (lambda d: estimate(d, "oe", [2, 2, 2], init="abc"),
     "oe[2 2 2]: init must be a PolyModel or a vector of its 4 parameters [a b c d f], got 'abc'"),
    (lambda d: estimate(d, "oe", [2, 2, 2], initial_condition="abc"),
     "oe: initial_condition must be one of ('zero', 'estimate', 'backcast', 'auto'), got 'abc'"),
    (lambda d: compare(d, true_model("oe"), horizon="1"), "prediction horizon must be a positive integer or inf, got '1'"),
    (lambda d: true_model("oe").predict(d, 2.5), "prediction horizon must be a positive integer or inf, got 2.5"),
    (lambda d: true_model("oe").predict(d, math.nan), "prediction horizon must be a positive integer or inf, got nan"),
])
def test_unclear_arguments_are_named_with_what_was_expected(data, call, needle):
    with refused(needle):
        call(data)


@pytest.mark.parametrize("text, needle", [
    ("garbage{", "PolyModel.from_json: not JSON (Expecting value at line 1 column 1)"),
    ("[" * 100_000 + "]" * 100_000, "PolyModel.from_json: the JSON is nested too deeply to be a model"),
    ('{"A":' * 100_000 + "1" + "}" * 100_000, "PolyModel.from_json: the JSON is nested too deeply to be a model"),
    (5, "PolyModel.from_json: expected the JSON text of a model (str), got int"),
    ("[1, 2]", "PolyModel.from_dict: expected a dict, got list"),
])
def test_garbage_or_deeply_nested_json_is_no_model(text, needle):
    with refused(needle):
        PolyModel.from_json(text)
