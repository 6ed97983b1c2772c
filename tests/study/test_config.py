"""The study's Hydra configs: composition, schemas, clear errors before any run exists."""

from __future__ import annotations

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf
from omegaconf.errors import ConfigKeyError, ValidationError

from maglev.structures import get as structure
from maglev.study import schema  # noqa: F401  (registers schemas and ${maglev.root:})
from maglev.study.config import StudyConfigError, check, config_hash, plain_config

from .harness import CONF, REPO, all_runs, launch

SIM = sorted(p.stem for p in (CONF / "dataset").glob("*.yaml") if not p.stem.startswith("real_"))
REAL = sorted(p.stem for p in (CONF / "dataset").glob("real_*.yaml") if p.stem != "real_record")
STRUCTURES = ["arx", "armax", "oe", "bj"]

pytestmark = pytest.mark.filterwarnings("ignore:The .*noload.* loader strategy is deprecated")


def cfg_for(overrides=(), hydra=False):
    with initialize_config_dir(version_base="1.3", config_dir=str(CONF)):
        return compose("config", overrides=list(overrides), return_hydra_config=hydra)


def task(cfg):
    return plain_config(OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]))


def test_default_config_is_simulated_data_into_a_local_store():
    c = task(cfg_for())
    assert c["dataset"]["name"] == "uniform_wide" and c["dataset"]["source"] == "sim"
    assert c["structure"]["name"] == "arx"
    assert c["tracking"]["uri"] == f"sqlite:///{REPO}/mlruns/mlflow.db"
    assert c["tracking"]["artifact_location"] == f"{REPO}/mlruns/artifacts"
    check(c)  # needs nothing but the repository


@pytest.mark.parametrize("name", SIM + REAL)
def test_every_dataset_composes(name):
    c = task(cfg_for([f"dataset={name}"]))
    if name.startswith("real_choice_"):  # the record rule's choice: a real record's config (its own name
        assert c["dataset"]["name"] in set(REAL) - {name} or c["dataset"]["name"] == name  # without the records)
    else:
        assert c["dataset"]["name"] == name
    assert c["dataset"]["input_class"] in ("uniform", "binary")
    assert set(c["dataset"]["preprocess"]) == {"trim", "detrend", "decimate", "split"}
    if name in SIM:
        check(c)


@pytest.mark.parametrize("name", SIM)
def test_simulated_datasets_give_the_lab_minimum_of_estimation_and_validation_data(name):
    """Lab §3.4: at least 10 s of estimation and 7 s of validation data."""
    from maglev.study.datasets import load

    c = task(cfg_for([f"dataset={name}"]))
    prepared = load(c["dataset"], c["data_dir"])
    assert prepared.est.N * prepared.est.Ts >= 10.0
    assert prepared.val.N * prepared.val.Ts >= 7.0


def test_real_file_variables_follow_the_refdata_readme():
    d1 = task(cfg_for(["dataset=real_binary_signal_1"]))["dataset"]
    assert (d1["u"], d1["y"], d1["Ts"]) == ("ub", "yb", 0.001)
    assert task(cfg_for(["dataset=real_white_noise_1"]))["dataset"]["u"] == "u1"
    d2 = task(cfg_for(["dataset=real_white_noise_2"]))["dataset"]
    assert (d2["u"], d2["y"]) == ("u2", "y2")


def test_data_dir_defaults_beside_the_repo_and_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("MAGLEV_REFDATA", raising=False)
    assert task(cfg_for())["data_dir"] == f"{REPO}/../shared/refdata"
    monkeypatch.setenv("MAGLEV_REFDATA", str(tmp_path))
    c = task(cfg_for(["dataset=real_white_noise_2"]))
    assert c["data_dir"] == str(tmp_path)
    with pytest.raises(StudyConfigError, match="MAGLEV_REFDATA"):
        check(c)  # the file is not in tmp_path: a clear error, before any run


@pytest.mark.parametrize("name", STRUCTURES)
def test_structures_and_order_overrides(name):
    c = task(cfg_for([f"structure={name}", "structure.order=3", "structure.nk=1"]))["structure"]
    keys = structure(name).orders
    assert [c[k] for k in keys] == [3] * (len(keys) - 1) + [1]
    one = keys[0]
    c = task(cfg_for([f"structure={name}", f"structure.{one}=4"]))["structure"]
    assert c[one] == 4 and all(c[k] == 2 for k in keys[1:-1])


@pytest.mark.parametrize("overrides, needle", [
    (["structure.nx=2"], "nx"),  # typo
    (["structure.na=two"], "structure.na"),  # wrong type
    (["structure=oe", "structure.na=2"], "na"),  # OE has no A polynomial
    (["dataset.low=abc"], "dataset.low"),
    (["dataset.preprocess.decimate=1.5"], "decimate"),
    (["structure.initial_condition=guess"], "initial_condition"),
    (["study.resid_lag=3"], "resid_lag"),
    (["dataset=nope"], "dataset/nope"),  # unknown dataset
    (["structure=nope"], "structure/nope"),  # unknown structure
])
def test_mistakes_fail_at_composition_naming_the_key(overrides, needle):
    with pytest.raises((ConfigCompositionException, ValidationError, ConfigKeyError)) as err:
        task(cfg_for(overrides))
    text = str(err.value) + str(err.value.__cause__)
    assert needle in text


def test_semantic_errors_are_refused_before_a_run():
    with pytest.raises(StudyConfigError, match="nb"):
        check(task(cfg_for(["structure=oe", "structure.nb=0"])))
    with pytest.raises(StudyConfigError, match="split"):
        check(task(cfg_for(["dataset.preprocess.split=1.5"])))
    with pytest.raises(StudyConfigError, match="alpha"):
        check(task(cfg_for(["dataset=binary_a025", "dataset.alpha=null"])))
    names = r"\['dry_friction', 'quiet_ageing', 'stick_slip', 'stretched_sensor', 'stuck_stretched', 'stuck_upper'\]"
    with pytest.raises(StudyConfigError, match=rf"dataset.plant must be one of {names}.*'nope'"):
        check(task(cfg_for(["dataset.plant=nope"])))


def test_simulated_datasets_name_their_plant_and_older_configs_keep_theirs():
    """Every simulated dataset names the simulator's parameter set; a config logged before the key existed
    (2026-11-23) is read as the plant of that time, so its runs reproduce (test_reproduce_fixture.py)."""
    from maglev.sim.plant import DEFAULT_PLANT, PLANTS, rig
    from maglev.study.datasets import UNNAMED_PLANT, load_raw, plant_name

    ds = task(cfg_for(["dataset=binary_a025", "dataset.duration_s=2"]))["dataset"]
    assert ds["plant"] == DEFAULT_PLANT
    assert set(PLANTS) == {DEFAULT_PLANT, "stick_slip", "stuck_upper", "stretched_sensor", "quiet_ageing",
                           UNNAMED_PLANT}
    old = {k: v for k, v in ds.items() if k != "plant"}
    assert plant_name(old) == UNNAMED_PLANT
    new_y, old_y = load_raw(ds, "").y, load_raw(old, "").y
    assert not np.allclose(new_y, old_y)
    u = load_raw(ds, "").u
    assert np.array_equal(old_y, rig(UNNAMED_PLANT).simulate(u, seed=ds["seed"]).y)
    assert rig(UNNAMED_PLANT).params.d == 4.2 and rig().params.d == 10.0


def test_schema_is_reapplied_to_a_saved_config():
    saved = OmegaConf.create(OmegaConf.to_yaml(cfg_for()))
    saved.structure.na = "two"
    with pytest.raises(ValidationError, match="structure.na"):
        schema.typed(saved)


@pytest.mark.parametrize("dataset", ["binary_a025", "real_binary_signal_2"])
@pytest.mark.parametrize("name", ["arx", "armax", "oe", "bj"])
def test_a_composed_config_already_has_the_schemas_typed_would_merge(dataset, name):
    """typed() returns a config as Hydra composed it, whose schema merge would change nothing, and merges
    the schemas into the same config read back from YAML (which has lost them): the same plain config."""
    cfg = cfg_for([f"dataset={dataset}", f"structure={name}"])
    composed = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    merged = OmegaConf.merge(OmegaConf.structured(schema.Config), {
        "dataset": OmegaConf.structured(schema.DATASET_SCHEMAS[composed.dataset.source]),
        "structure": OmegaConf.structured(schema.register_structure(name))}, composed)
    saved = OmegaConf.create(OmegaConf.to_yaml(composed))
    assert schema.typed(composed) is composed and schema.typed(saved) is not saved
    assert OmegaConf.get_type(schema.typed(saved), "structure") is schema.register_structure(name)
    assert plain_config(composed) == plain_config(saved) == OmegaConf.to_container(
        merged, resolve=True, enum_to_str=True, throw_on_missing=True)


def test_config_hash_ignores_shorthand_tracking_and_names():
    a = task(cfg_for(["structure=bj", "structure.order=2"]))
    b = task(cfg_for(["structure=bj", "structure.order=3", "structure.nb=2", "structure.nc=2",
                      "structure.nd=2", "structure.nf=2", "tracking.uri=sqlite:////elsewhere.db",
                      "study.name=other"]))
    c = task(cfg_for(["structure=bj", "structure.nf=3"]))
    assert config_hash(a) == config_hash(b) != config_hash(c)


@pytest.mark.parametrize("name, n_datasets", [("lab", 3), ("lab_real", 3)])
def test_sweep_configs_declare_the_sweep(name, n_datasets):
    cfg = cfg_for([f"+sweep={name}"], hydra=True)
    params = cfg.hydra.sweeper.params
    datasets = params["dataset"].split(",")
    assert len(datasets) == n_datasets and len(params["structure"].split(",")) >= 3
    assert len(params["structure.order"].split(",")) >= 2
    assert str(cfg.hydra.mode) == "RunMode.MULTIRUN" and cfg.study.name == name
    classes = {task(cfg_for([f"+sweep={name}", f"dataset={d}"]))["dataset"]["input_class"] for d in datasets}
    assert classes == {"uniform", "binary"}
    if name == "lab":
        inputs = [task(cfg_for([f"dataset={d}"]))["dataset"]["input_class"] for d in datasets]
        assert inputs.count("uniform") == 2 and inputs.count("binary") == 1


def test_launcher_configs_exist():
    cfg = cfg_for(["hydra/launcher=parallel"], hydra=True)
    assert cfg.hydra.launcher.n_jobs == 2
    assert cfg.hydra.launcher._target_ == "hydra_plugins.maglev_launcher.parallel.JoblibLauncher"  # joblib's
    assert cfg_for(hydra=True).hydra.launcher._target_.endswith("BasicLauncher")
    assert (CONF / "hydra" / "launcher" / "slurm.yaml").is_file()


def test_the_cluster_entries_compose_to_a_server_from_mlflows_variables_and_maglevs_slurm_launcher(monkeypatch):
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://login1:5000")
    cfg = cfg_for(["tracking=cluster", "hydra/launcher=slurm"], hydra=True)
    plain = task(cfg)
    assert plain["tracking"]["uri"] == "http://login1:5000" and plain["tracking"]["artifact_location"] is None
    assert plain["tracking"]["max_retries"] == 7 and not plain["tracking"]["reap"]
    check(plain)
    assert cfg.hydra.launcher._target_ == "hydra_plugins.maglev_launcher.slurm.SlurmLauncher"
    assert cfg.hydra.launcher.timeout_min == 30 and cfg.hydra.launcher.mem_gb == 4


def test_real_record_base_is_not_a_dataset_on_its_own():
    with pytest.raises(Exception, match="dataset.name|Missing mandatory value"):
        task(cfg_for(["dataset=real_record"]))


@pytest.mark.parametrize("overrides, needle", [
    (["structure.na=abc"], "structure.na"),
    (["structure=arx,oe", "structure.na=abc"], "structure.na"),
    (["dataset=nope"], "dataset/nope"),
])
def test_a_mistake_in_a_launch_creates_no_run(tmp_path, overrides, needle):
    with pytest.raises(Exception) as err:
        launch(tmp_path, *overrides)
    assert needle in str(err.value) + str(err.value.__cause__)
    db = tmp_path / "mlflow.db"
    assert not db.exists() or all_runs(tmp_path)[2] == []


def test_a_sweep_estimates_the_blas_its_runs_need_in_the_background_once(monkeypatch, tmp_path):
    """prepare_blas: one background process for the simulated datasets that log BLA distances (true_plant),
    each class once, and nothing when the disk cache has them all."""
    from maglev.sim.bla import is_cached
    from maglev.study.datasets import _bla_preprocess, prepare_blas, sim_spec

    monkeypatch.setenv("MAGLEV_CACHE", str(tmp_path))  # read by the spawned process too
    # 2 s records: which BLAs are made, where and how often does not depend on their length; each BLA simulates
    # 256 records of its class (the two classes of 4 s took 4.4 s of CPU, of 2 s 2.9 s)
    def job(*overrides, short=("dataset.duration_s=2", "dataset.preprocess.trim=500")):
        return task(cfg_for([*overrides, *short]))

    narrow, binary = job("dataset=uniform_narrow"), job("dataset=binary_a025", "structure=oe")
    lean, real = job("dataset=uniform_wide", "study.true_plant=false"), job("dataset=real_white_noise_2", short=())
    proc = prepare_blas([narrow, binary, job("dataset=uniform_narrow", "structure=bj"), lean, real])
    proc.join(120)
    assert proc.exitcode == 0
    made = {p.stem for p in (tmp_path / "bla").glob("*.npz")}
    assert len(made) == 2  # narrow once, binary; not the lean or the real record
    for cfg in (narrow, binary):
        assert is_cached(sim_spec(cfg["dataset"]), preprocess=_bla_preprocess(cfg["dataset"]))
    assert not is_cached(sim_spec(lean["dataset"]), preprocess=_bla_preprocess(lean["dataset"]))
    assert prepare_blas([narrow, binary]) is None
