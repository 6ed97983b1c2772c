"""The declarative study: Hydra sweeps of datasets × structures × orders, tracked in MLflow.

Hydra, OmegaConf and MLflow are imported only in this package.  One module per job:

* :mod:`~maglev.study.schema`    structured-config schemas (typos and wrong types fail at composition)
* :mod:`~maglev.study.config`    the resolved config as plain data: checks, identity (hash), params
* :mod:`~maglev.study.datasets`  dataset loading and preprocessing (no Hydra, no MLflow)
* :mod:`~maglev.study.identify`  one identification run → model, metrics (no Hydra, no MLflow)
* :mod:`~maglev.study.figures`   the study's figures: a run's four, the ranking's, orders (matplotlib)
* :mod:`~maglev.study.lab`       the lab-level steps logged once per sweep (no Hydra, no MLflow)
* :mod:`~maglev.study.tracking`  MLflow, writing side: store, experiment, logging, queries
* :mod:`~maglev.study.store`     MLflow, reading side: a sweep's parent, runs and artifacts
* :mod:`~maglev.study.job`       one Hydra job = one MLflow run (skip, fail, finish)
* :mod:`~maglev.study.resume`    a relaunch with nothing to do, decided from one read of the store
* :mod:`~maglev.study.compose`   each job's config composed once per launch
* :mod:`~maglev.study.progress`  what a running sweep says about itself, and the time left
* :mod:`~maglev.study.lazy`      modules imported on first use (a launch that ends early never loads MLflow)
* :mod:`~maglev.study.heap`      full garbage collections held off while a study process imports
* :mod:`~maglev.study.sweeper`   the jobs of a sweep: every combination, with an order grid per structure
* :mod:`~maglev.study.callbacks` the sweep's parent run and its end-of-sweep ranking (Hydra callbacks)
* :mod:`~maglev.study.ranking`   rank a sweep, the lab's comparisons, the ranking run
* :mod:`~maglev.study.report`    the lab report (HTML), one function per section in ``report.sections``
* :mod:`~maglev.study.reproduce` recompute a run from its logged config
* :mod:`~maglev.study.reap`      mark runs left RUNNING by dead processes as KILLED
* :mod:`~maglev.study.shutdown`  SIGTERM ends a sweep like Ctrl-C: nothing left RUNNING
* :mod:`~maglev.study.ui`        the MLflow UI on the store, started lightly
* :mod:`~maglev.study.cli`       the ``maglev`` command

The run schema (tags, params, metrics, artifact paths) is documented in ``docs/tracking.md``.
"""
