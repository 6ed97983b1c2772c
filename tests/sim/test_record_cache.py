"""The disk cache of simulated records (maglev.sim.record_cache): a hit is the simulation, bit for bit."""

import os

import numpy as np
import pytest

from maglev.sim import labdata, record_cache
from maglev.sim.labdata import ExperimentSpec
from maglev.sim.plant import Levitator, rig

SPEC = ExperimentSpec("binary", 1.5, 3.5, alpha=0.25, duration_s=1.0, seed=3)


@pytest.fixture(autouse=True)
def cache_here(tmp_path, monkeypatch):
    monkeypatch.setenv("MAGLEV_CACHE", str(tmp_path))
    return tmp_path / "records"


def same(a, b) -> None:
    assert (a.name, a.Ts, a.u_offset, a.y_offset) == (b.name, b.Ts, b.u_offset, b.y_offset)
    assert np.array_equal(a.u, b.u) and np.array_equal(a.y, b.y)
    assert a.meta.keys() == b.meta.keys()
    for key, value in a.meta.items():
        if isinstance(value, np.ndarray):
            assert np.array_equal(value, b.meta[key]) and value.dtype == b.meta[key].dtype, key
        else:
            assert value == b.meta[key], key


def test_a_cached_record_is_the_simulated_one_bit_for_bit_and_is_read_without_simulating(cache_here, monkeypatch):
    fresh = labdata.experiment(SPEC)
    first = labdata.experiment(SPEC, cache=True)  # simulated and saved
    assert [p.suffix for p in cache_here.iterdir()] == [".npz"]
    same(first, fresh)

    def refuse(*args, **kwargs):
        raise AssertionError("simulated although cached")

    monkeypatch.setattr(Levitator, "simulate", refuse)
    again = labdata.experiment(SPEC, cache=True)
    same(again, fresh)
    assert not again.u.flags.writeable  # an IOData as any other
    with pytest.raises(AssertionError, match="simulated although cached"):
        labdata.experiment(SPEC)  # without cache=True it simulates


def test_the_key_holds_the_spec_the_name_the_plant_and_the_code(monkeypatch):
    plant = rig()
    key = record_cache.cache_key(SPEC, "r", plant)
    assert key == record_cache.cache_key(ExperimentSpec("binary", 1.5, 3.5, alpha=0.25, duration_s=1.0, seed=3),
                                         "r", rig())
    others = [record_cache.cache_key(ExperimentSpec("binary", 1.5, 3.5, alpha=0.25, duration_s=1.0, seed=4), "r",
                                     plant),
              record_cache.cache_key(SPEC, "s", plant),
              record_cache.cache_key(SPEC, "r", plant.with_params(noise_std=2 * plant.params.noise_std)),
              record_cache.cache_key(SPEC, "r", Levitator(plant.params, zero_at_10=False))]
    assert len({key, *others}) == 5
    monkeypatch.setattr(record_cache, "_code_digest", lambda: "an edited simulator")
    assert record_cache.cache_key(SPEC, "r", plant) != key


def test_an_unreadable_entry_is_simulated_again_and_replaced(cache_here):
    fresh = labdata.experiment(SPEC, cache=True)
    [entry] = cache_here.iterdir()
    entry.write_bytes(b"half a file")
    same(labdata.experiment(SPEC, cache=True), fresh)
    same(record_cache._load(entry), fresh)


def test_the_least_recently_used_entries_beyond_keep_are_removed(cache_here, monkeypatch):
    monkeypatch.setattr(record_cache, "KEEP", 2)
    specs = [ExperimentSpec("uniform", 1.5, 3.5, duration_s=0.1, seed=s) for s in range(3)]
    paths = []
    for age, spec in enumerate(specs):
        labdata.experiment(spec, cache=True)
        [path] = set(cache_here.glob("*.npz")) - set(paths)
        os.utime(path, (1e9 + age, 1e9 + age))  # written in this order, a second apart
        paths.append(path)
        if age == 1:
            labdata.experiment(specs[0], cache=True)  # read again: the first is now the most recently used
    assert sorted(cache_here.glob("*.npz")) == sorted([paths[0], paths[2]])


def test_an_entry_is_written_whole_or_not_at_all(tmp_path):
    """maglev.paths.save_npz, which the BLA cache uses too: a file beside the entry renamed over it (no temporary
    file left), and False where the directory cannot be written (a file stands where it should be)."""
    from maglev.paths import save_npz

    path = tmp_path / "cache" / "entry.npz"
    assert save_npz(path, a=np.arange(3.0))
    assert [p.name for p in path.parent.iterdir()] == ["entry.npz"]
    with np.load(path) as z:
        assert np.array_equal(z["a"], np.arange(3.0))
    (tmp_path / "blocked").write_text("a file, not a directory")
    assert not save_npz(tmp_path / "blocked" / "entry.npz", a=np.arange(3.0))
