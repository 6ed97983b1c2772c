"""IOData: loading the lab's files, preprocessing, and clear errors for bad input."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.io import savemat

from maglev.data import IOData


def test_from_mat_reads_row_and_uint8_vectors_and_ts(tmp_path):
    path = tmp_path / "rec.mat"
    savemat(path, {"u": np.full((1, 50), 3, dtype=np.uint8), "y": np.arange(50.0)[:, None], "Ts": 0.002})
    d = IOData.from_mat(path)
    assert d.u.dtype == np.float64 and d.u.shape == (50,) and np.all(d.u == 3)
    assert d.Ts == 0.002 and d.name == "rec" and len(d) == 50


def test_from_mat_without_ts_needs_it(tmp_path):
    path = tmp_path / "nots.mat"
    savemat(path, {"ub": np.ones(20), "yb": np.zeros(20)})
    with pytest.raises(ValueError, match="no variable 'Ts'.*pass Ts="):
        IOData.from_mat(path, u="ub", y="yb")
    assert IOData.from_mat(path, u="ub", y="yb", Ts=0.001).Ts == 0.001


def test_from_mat_names_missing_variable_and_what_is_there(tmp_path):
    path = tmp_path / "x.mat"
    savemat(path, {"u1": np.ones(20), "y1": np.zeros(20), "Ts": 0.001})
    with pytest.raises(ValueError, match=r"x.mat: no variable 'u'; the file holds \['Ts', 'u1', 'y1'\]"):
        IOData.from_mat(path)


def test_from_csv_round_trip_and_bad_cell(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("u,y\n" + "\n".join(f"{i},{2 * i}" for i in range(30)))
    d = IOData.from_csv(path, Ts=0.01)
    assert np.array_equal(d.y, 2 * d.u)
    bad = tmp_path / "bad.csv"
    bad.write_text("u,y\n" + "\n".join(f"{i},{'oops' if i == 4 else i}" for i in range(30)))
    with pytest.raises(ValueError, match="bad.csv: column 'y' row 6 is 'oops'"):
        IOData.from_csv(bad, Ts=0.01)
    with pytest.raises(ValueError, match="pass Ts="):
        IOData.from_csv(path)
    timed = tmp_path / "t.csv"
    timed.write_text("u,y,Ts\n" + "\n".join(f"{i},{i},0.002" for i in range(30)))
    assert IOData.from_csv(timed).Ts == 0.002
    varying = tmp_path / "v.csv"
    varying.write_text("u,y,Ts\n" + "\n".join(f"{i},{i},{0.001 * (1 + i % 2)}" for i in range(30)))
    with pytest.raises(ValueError, match=r"v.csv: column 'Ts' must hold one constant sampling period, got 2 "
                                         r"different values \(0.001, 0.002\)"):
        IOData.from_csv(varying)
    # a time column gives Ts; units in the header name the column
    clock = tmp_path / "c.csv"
    clock.write_text("t (s),u (A),y (cm)\n" + "\n".join(f"{0.003 * i!r},{i},{-i}" for i in range(30)))
    d = IOData.from_csv(clock)
    assert d.Ts == 0.003 and np.array_equal(d.y, -d.u)
    jitter = tmp_path / "j.csv"
    jitter.write_text("t,u,y\n" + "\n".join(f"{0.001 * i + (0.0004 if i == 7 else 0)},{i},{i}" for i in range(30)))
    with pytest.raises(ValueError, match=r"j.csv: time column 't' is not uniformly spaced"):
        IOData.from_csv(jitter)


@pytest.mark.parametrize(
    "u, y, Ts, message",
    [
        (np.ones(20), np.ones(19), 1.0, "20 samples but output y has 19"),
        (np.r_[np.ones(19), np.nan], np.ones(20), 1.0, "1 NaN/inf value.*index 19"),
        (np.ones(20), np.r_[np.inf, np.ones(19)], 1.0, "output y has 1 NaN/inf"),
        (np.ones(20), np.ones(20), 0.0, "Ts must be a positive number"),
        (np.ones(20), np.ones(20), -1e-3, "Ts must be a positive number"),
        (np.ones(20), np.ones(20), True, "Ts must be a positive number of seconds, got True"),
        (np.ones(20), np.ones(20), "1", "Ts must be a positive number of seconds, got '1'"),
        (np.ones(5), np.ones(5), 1.0, "too few"),
        (np.ones((20, 2)), np.ones(20), 1.0, "one channel"),
    ],
)
def test_bad_records_are_refused_with_a_clear_message(u, y, Ts, message):
    with pytest.raises(ValueError, match=message):
        IOData(u, y, Ts, name="rec")


def test_detrend_keeps_offsets_and_split_trim_decimate():
    rng = np.random.default_rng(0)
    u = 2.75 + rng.standard_normal(1000)
    y = 8.5 + rng.standard_normal(1000)
    d = IOData(u, y, 1e-3, name="r").detrend()
    assert abs(d.u.mean()) < 1e-12 and d.u_offset == pytest.approx(u.mean())
    np.testing.assert_allclose(d.y + d.y_offset, y)
    est, val = d.split(0.5)
    assert len(est) == len(val) == 500 and np.array_equal(val.u, d.u[500:])
    assert len(d.trim(0.25)) == 750 and len(d.trim(100)) == 900
    dec = d.decimate(4)
    assert len(dec) == 250 and dec.Ts == pytest.approx(4e-3)
    np.testing.assert_allclose(d.t[:3], [0, 1e-3, 2e-3])
    with pytest.raises(ValueError, match="split fraction must be in"):
        d.split(1.0)
    with pytest.raises(ValueError, match="decimation factor must be a positive integer"):
        d.decimate(0)
    with pytest.raises(ValueError, match="cannot trim 1000 of 1000"):
        d.trim(1000)


def test_decimate_keeps_low_frequency_content():
    t = np.arange(4000)
    u = np.sin(2 * np.pi * t / 400)
    d = IOData(u, 2 * u, 1.0).decimate(5)
    core = slice(50, -50)  # away from the filter's edge effects; Chebyshev ripple 0.05 dB, twice (zero phase)
    np.testing.assert_allclose(d.u[core], np.sin(2 * np.pi * np.arange(800)[core] * 5 / 400), atol=1.5e-2)


def test_real_files_load(refdata):
    d = refdata / "el2820_maglev_2022"
    assert len(IOData.from_mat(d / "binary_signal_2.mat")) == 20000
    assert len(IOData.from_mat(d / "white_noise_2.mat", u="u2", y="y2")) == 20000
    b1 = IOData.from_mat(d / "binary_signal_1.mat", u="ub", y="yb", Ts=0.001)
    assert b1.u.min() == pytest.approx(1.5) and b1.u.max() == pytest.approx(3.0)
    csv = IOData.from_csv(d / "binary_signal_2.csv", Ts=0.001)
    np.testing.assert_array_equal(csv.y, IOData.from_mat(d / "binary_signal_2.mat").y)
