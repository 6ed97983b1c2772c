"""Each choice of config groups composed once (:mod:`maglev.study.compose`): every job's config is Hydra's own."""

from __future__ import annotations

from pathlib import Path

import io
import re

import pytest
from omegaconf import OmegaConf

CONF = Path(__file__).resolve().parents[2] / "conf"


def test_every_job_of_the_lab_sweep_gets_hydras_own_config_from_one_composition_per_choice_of_groups():
    """The default sweep's jobs (3 datasets × 4 structures × their orders, 39): the memoised loader gives each
    job exactly the config Hydra composes for it (values, ``hydra.overrides.task``, the job's folder name),
    twice (the sweeper's validation, then the launcher), each time a copy of its own, from 12 compositions."""
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import RunMode

    import maglev.study.schema  # noqa: F401
    from maglev.study.callbacks import sweep_jobs
    from maglev.study.compose import memoise

    with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):
        loader = GlobalHydra.instance().config_loader()
        master = loader.load_configuration("config", ["+sweep=lab", "tracking.uri=sqlite:////tmp/x/mlflow.db",
                                                      "hydra.sweep.dir=/tmp/x"], run_mode=RunMode.MULTIRUN)
        jobs = sweep_jobs(master)
        sweeper = master.hydra.sweeper  # a structure's own orders (sweeper.orders), else structure.order's
        assert len(jobs) == 3 * sum(len(str(sweeper.orders.get(s, sweeper.params["structure.order"])).split(","))
                                    for s in ("arx", "armax", "oe", "bj")) == 39
        own = {tuple(job): OmegaConf.to_yaml(type(loader).load_sweep_config(loader, master, job)) for job in jobs}
        assert len(set(own.values())) == len(jobs)
        composed = []
        compose = loader.load_sweep_config

        def counted(master_config, overrides):
            composed.append(tuple(overrides))
            return compose(master_config, overrides)

        loader.load_sweep_config = counted
        memoise(loader)
        for _ in ("validation", "launch"):
            configs = [loader.load_sweep_config(master, job) for job in jobs]
            assert [OmegaConf.to_yaml(cfg) for cfg in configs] == [own[tuple(job)] for job in jobs]
            configs[0].structure.name = "changed"  # a job's config is its own
        assert len(composed) == len(set(composed)) == 12
        assert configs[0].hydra.job.override_dirname == "dataset=uniform_narrow,structure.order=4,structure=arx"


def test_a_composition_from_files_parsed_once_is_hydras_own_and_each_load_a_new_config(monkeypatch, tmp_path):
    """Each config file's YAML is parsed once per process (:func:`maglev.study.compose.parse_each_file_once`,
    installed by importing the schemas): the default sweep's composition is the one OmegaConf's own loader
    gives, a file read again is not parsed again, and each load is a config of its own (Hydra edits them)."""
    import yaml
    from hydra import compose, initialize_config_dir

    import maglev.study.schema  # noqa: F401

    def composed():
        with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):
            return OmegaConf.to_yaml(compose("config", ["+sweep=lab", "dataset=binary_a025", "structure=bj"],
                                             return_hydra_config=True))

    once = composed()
    with monkeypatch.context() as own:
        own.setattr(OmegaConf, "load", staticmethod(OmegaConf.load.original))
        assert composed() == once

    path = tmp_path / "fresh.yaml"
    path.write_text(f"defaults:\n  - base\nname: {tmp_path.name}\nx: [1, 2.5e-3, .inf]\n")
    parses = []
    parse = yaml.load
    monkeypatch.setattr(yaml, "load", lambda *args, **kwargs: parses.append(1) or parse(*args, **kwargs))
    loads = []
    for _ in range(3):
        with open(path, encoding="utf-8") as f:
            loads.append(OmegaConf.load(f))
    assert len(parses) == 1
    loads[0].pop("defaults")  # as Hydra does with what it loads
    assert loads[1] == loads[2] == OmegaConf.load.original(path) and "defaults" not in loads[0]


def test_a_config_file_that_does_not_parse_is_refused_naming_it(tmp_path):
    import yaml

    import maglev.study.schema  # noqa: F401

    path = tmp_path / "broken.yaml"
    path.write_text("name: x\nx: [1, 2\n")
    where = re.escape(f'in "{path}", line 3')
    for _ in range(2):
        with open(path, encoding="utf-8") as f, pytest.raises(yaml.YAMLError, match=where):
            OmegaConf.load(f)


@pytest.mark.parametrize("encoding", ["utf-8", "utf-16"])
def test_a_config_read_as_bytes_is_what_omegaconfs_loader_makes_of_them(encoding):
    """A zipped package's config files reach OmegaConf.load as bytes, whose encoding YAML detects."""
    import maglev.study.schema  # noqa: F401

    raw = f"name: bytes_{encoding}\nx: [1, 2.5e-3]\n".encode(encoding)
    expected = OmegaConf.load.original(io.BytesIO(raw))
    assert OmegaConf.load(io.BytesIO(raw)) == OmegaConf.load(io.BytesIO(raw)) == expected
    assert expected.name == f"bytes_{encoding}"
