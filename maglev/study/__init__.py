"""The declarative study: Hydra sweeps of datasets × structures × orders, tracked in MLflow.

One module per job, so each stays short:

* :mod:`~maglev.study.schema`   structured-config schemas (typos and wrong types fail early)
* :mod:`~maglev.study.datasets` dataset loading and preprocessing (no Hydra, no MLflow)
* :mod:`~maglev.study.identify` one identification run → model, metrics, figures (no Hydra, no MLflow)
* :mod:`~maglev.study.figures`  the run's PNG figures (matplotlib only)
* :mod:`~maglev.study.lab`      the lab-level steps logged once per sweep (no Hydra, no MLflow)
* :mod:`~maglev.study.tracking` everything MLflow: store, experiment, hashing, logging, queries
* :mod:`~maglev.study.job`      one Hydra job = one MLflow run (skip, fail, finish)
* :mod:`~maglev.study.callback` the sweep's parent run (Hydra callback)
* :mod:`~maglev.study.reap`     mark runs left RUNNING by dead processes as KILLED

The run schema (tags, params, metrics, artifact paths) is documented in ``docs/tracking.md``.
Only ``tracking``, ``job``, ``callback``, ``reap`` and ``schema`` import MLflow or Hydra.
"""
