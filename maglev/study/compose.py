"""Each choice of config groups composed once per sweep, not once per job and twice.

Hydra's basic sweeper composes every job's config to validate the batch
(``Sweeper.validate_batch_is_legal``) and the basic launcher composes it again to run it.  Composing
costs ≈ 90 ms of CPU per job and copying a composed config ≈ 4 ms (2-core machine, side by side).
Jobs that differ only in plain values (``structure.order=4`` and ``=5``) share their composition:
:func:`memoise` composes each job's config groups (``dataset=…``, ``structure=…``, ``+sweep=…``) once,
and a job's config is a copy of it with the job's plain value overrides applied by Hydra's own
function, its ``hydra.overrides.task`` and ``hydra.job.override_dirname`` as Hydra sets them
(``tests/study/test_compose.py`` checks that every job's config equals Hydra's own composition).
The default sweep composes 12 configs instead of 42.  The sweep callback installs it before its
own check (:func:`maglev.study.callbacks.check_sweep`, which shares the compositions); the
launchers that compose in other processes (joblib, submitit) are left alone.

Every composition reads each of its YAML files again (13 for a job of the default sweep), and parsing
the YAML is an eighth of a composition's time: :func:`parse_each_file_once` keeps what each file's text
parses to for the process (installed when :mod:`maglev.study.schema` is imported: in ``study.py`` before
it composes; a joblib worker's first job has composed by then).

A signal that arrives while a config is composed, or while Hydra edits it before its job starts, is raised
at the next call here or at the job's start (:func:`maglev.study.shutdown.between_jobs`): raised inside
OmegaConf, its exit was replaced by OmegaConf's own error.
"""

from __future__ import annotations

import copy

_PARSED: dict[str | bytes, object] = {}  # a config file's text -> its YAML, parsed once per process


def split_overrides(parsed, repository) -> tuple[list, tuple[str, ...]]:
    """A job's parsed overrides as (those that set a value on the composed config, what Hydra applies after
    composing the defaults; the input lines of the others, which choose config groups, add, delete or move a
    key): jobs whose others are the same share one composition (here and in
    :func:`maglev.study.callbacks.check_sweep`)."""
    values, groups = [], []
    for o in parsed:
        if (o.is_add() or o.is_delete() or o.is_force_add() or o.package or o.is_hydra_override()
                or o.is_sweep_override() or repository.group_exists(o.key_or_group)):
            groups.append(o.input_line)
        else:
            values.append(o)
    return values, tuple(groups)


def memoise(loader) -> None:
    """Make ``loader.load_sweep_config`` (Hydra's config loader of this launch) compose each choice of config
    groups once and apply a job's plain value overrides to a copy."""
    if getattr(loader, "maglev_memo", None) is not None:
        return
    from hydra._internal.config_loader_impl import ConfigLoaderImpl, get_overrides_dirname
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import open_dict

    from maglev.study import shutdown

    compose = loader.load_sweep_config
    parser = OverridesParser.create()
    memo: dict[tuple, object] = {}

    def load_sweep_config(master_config, sweep_overrides):
        shutdown.raise_if_received()  # a signal held since the last config or job: raised here, outside OmegaConf
        with shutdown.deferred():
            cfg = composed(master_config, sweep_overrides)
        shutdown.between_jobs()  # Hydra edits it next (the job's number, run_job's copies): held until a job starts
        return cfg

    def composed(master_config, sweep_overrides):
        parsed = parser.parse_overrides(list(sweep_overrides))
        values, groups = split_overrides(parsed, loader.repository)
        key = (id(master_config), groups)
        if key not in memo:
            memo[key] = compose(master_config, list(groups))
        cfg = copy.deepcopy(memo[key])
        if not values:
            return cfg
        ConfigLoaderImpl._apply_overrides_to_config(values, cfg)
        task = [o for o in parsed if not o.is_hydra_override()]
        how = cfg.hydra.job.config.override_dirname
        with open_dict(cfg.hydra):
            cfg.hydra.overrides.task = [o.input_line for o in task]
            cfg.hydra.job.override_dirname = get_overrides_dirname(
                overrides=task, kv_sep=how.kv_sep, item_sep=how.item_sep, exclude_keys=how.exclude_keys)
        return cfg

    loader.load_sweep_config = load_sweep_config
    loader.maglev_memo = memo


def parse_each_file_once() -> None:
    """Make ``OmegaConf.load`` of a file (Hydra's only reader of config files) parse each text once per process
    and build the config from a copy of what it parsed; what OmegaConf.load returns is unchanged (a new config
    each time: Hydra edits what it loads).  A text that does not parse (or parses to what OmegaConf refuses),
    a path and a stream that cannot seek are handed to OmegaConf as before, whose error names the file."""
    import yaml
    from omegaconf import OmegaConf
    from omegaconf._utils import get_yaml_loader

    if getattr(OmegaConf.load, "parsed", None) is _PARSED:
        return
    load = OmegaConf.load

    def parsed_once(file_):
        if not (hasattr(file_, "read") and hasattr(file_, "seekable") and file_.seekable()):
            return load(file_)  # a path (OmegaConf opens it) or a stream that cannot be read again
        start = file_.tell()
        text = file_.read()  # str, or bytes (a zipped package's config: YAML detects their encoding)
        if text not in _PARSED:
            try:
                tree = yaml.load(text, Loader=get_yaml_loader())
                usable = tree is None or isinstance(tree, (list, dict, str))
            except yaml.YAMLError:
                usable = False
            if not usable:  # OmegaConf's own error, naming the file
                file_.seek(start)
                return load(file_)
            _PARSED[text] = tree
        return OmegaConf.create() if _PARSED[text] is None else OmegaConf.create(copy.deepcopy(_PARSED[text]))

    parsed_once.parsed, parsed_once.original = _PARSED, load
    OmegaConf.load = staticmethod(parsed_once)
