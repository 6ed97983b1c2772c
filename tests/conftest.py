"""Shared test fixtures: where the real lab recordings are, a non-interactive matplotlib, and an empty
MLflow store made once per session and copied."""

from __future__ import annotations

import gc
import os
import shutil
from pathlib import Path

# Two pytest workers on two cores, and the processes their tests start: a second BLAS thread in any of them
# only contends for a core that is busy (spinning OpenBLAS threads: the tests of tests/sim and tests/estimation
# took 7 % more CPU with two than with one).  The suite runs BLAS single-threaded, as bench/ does; set before
# numpy is first imported here, and inherited by every process a test starts.
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

import matplotlib  # noqa: E402
import pytest  # noqa: E402

matplotlib.use("Agg")  # before anything imports pyplot (python-control does)

from maglev.paths import refdata_dir  # noqa: E402
from maglev.study import heap  # noqa: E402

if os.environ.get("PYTEST_XDIST_WORKER"):
    heap.hold()  # while the worker collects (imports every test module and its libraries): see settled_libraries

REPO = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent

# The cluster harness (tests/cluster: Slurm, PostgreSQL, an MLflow server with auth) installs system packages
# and runs minutes: its own CI stage runs it with MAGLEV_CLUSTER=1; the suite's default run leaves it out.
collect_ignore_glob = [] if os.environ.get("MAGLEV_CLUSTER") == "1" else ["cluster/*"]

# Tests that start a real MLflow server (`mlflow server`, `maglev ui`, ≈ 6–10 s of a process each, and their
# waits) are a service stage of their own, like the cluster's: CI runs them after the suite with
# MAGLEV_SERVICE=1 (`python -m pytest -q -m service`, .ci/run); the suite's default run skips them, saying so.
SERVICE = (
    "study/test_server.py",
    "study/test_processes.py::test_a_server_killed_in_the_middle_of_a_sweep_ends_it_within_a_minute_leaving_no_process",
    "study/test_ui.py::test_sigterm_to_maglev_ui_stops_its_server",
    "study/test_sweep.py::test_maglev_ui_serves_the_store_lightly_opened_on_the_sweep_in_model_training_mode",
)
SERVICE_SKIP = pytest.mark.skip(reason="starts a real MLflow server: the service stage runs it "
                                       "(MAGLEV_SERVICE=1 python -m pytest -q -m service)")

# The README's command runs the suite in two pytest-xdist workers, whole files at a time (--dist loadfile),
# handing a worker its next file once it has at most 2 tests left.  xdist's default order (files with the
# most tests first) leaves the end-to-end files, a few tests of 5–35 s each, for last, and one worker
# idle while the other finishes them.  Longest first instead: CPU seconds of a file's tests and of the
# processes they start, summed per file (a full run, loaded 2-core machine), ordered by what each file also
# waits for (servers, signals, processes in parallel):
LONGEST_FIRST = (
    "study/test_report.py",       # 47: the default sweep, its BLAs estimated, ranked and reported
    "study/test_processes.py",    # 38: kill -9 of joblib's launcher, Ctrl-C, SIGTERM (a server killed: SERVICE)
    "study/test_concurrency.py",  # 40: two launches at once (twice), SIGTERM, kill -9
    "sim/test_calibrate.py",      # 24: the simulator's checks against the real records
    "study/test_server.py",       # 16 and its server's ~10 (SERVICE): submitit's jobs, a password in the URI
    "study/test_report_real.py",  # 25: the real sweep, ranked, reported and printed
    "study/test_sweep.py",        # 19: a sweep, maglev ui
    "estimation/test_nested_orders.py",  # 21
    "estimation/test_estimate_real.py",  # 19
    "study/test_hostile.py",      # 18: refusals as processes
    "study/test_config.py",       # 15
    "study/test_faults.py",       # 11
    "study/test_store.py",        # 10
    "study/test_ui.py",           # 8: maglev ui's server
    "study/test_parallel.py",     # joblib's worker processes
)


# The development loop `python -m pytest -q -m "not slow" -n 2` (docs/development.md) leaves out the tests that take
# seconds each: end-to-end sweeps and launches as processes, servers, the simulator's calibration, estimation on
# the real records' grids, Monte-Carlo.  Files marked slow themselves (pytestmark) are not repeated here; these
# are marked here, in one place, from the durations of a full `-m "not slow"` run (a whole file, or one test with
# all its parameters).  The full suite runs them all.
SLOW = (
    "study/test_sweep.py",               # a sweep shared by the file, maglev ui, single runs
    "study/test_resume.py",              # a ranked sweep shared by the file, a relaunch as a process
    "sim/test_calibrate.py",             # fitting the simulator
    "sim/test_sim_vs_real.py",           # simulating every real record
    "estimation/test_nested_orders.py",  # the nested-order grids on real data
    "estimation/test_estimate_real.py",  # BJ on the real records
    "study/test_config.py::test_a_sweep_estimates_the_blas_its_runs_need_in_the_background_once",
    "study/test_config.py::test_structures_and_order_overrides",
    "study/test_config.py::test_sweep_configs_declare_the_sweep",
    "study/test_config.py::test_semantic_errors_are_refused_before_a_run",
    "study/test_config.py::test_simulated_datasets_give_the_lab_minimum_of_estimation_and_validation_data",
    "study/test_config.py::test_a_mistake_in_a_launch_creates_no_run",
    "study/test_faults.py::test_a_closed_port_fails_at_once_in_one_line_naming_the_uri",
    "study/test_faults.py::test_a_sweep_with_an_impossible_config_is_refused_before_any_run",
    "study/test_faults.py::test_a_failed_run_has_its_error_tag_even_when_its_upload_fails_and_logs_its_config",
    "study/test_shutdown.py::test_a_signal_in_a_commit_is_raised_after_it_and_the_store_stays_writable",
    "study/test_shutdown.py::test_sigterm_inside_omegaconf_between_jobs_ends_the_sweep_at_once_with_its_one_line",
    "study/test_shutdown.py::test_a_sigterm_held_between_jobs_ends_the_sweep_as_one_would_inside_a_job",
    "study/test_shutdown.py::test_a_sweep_ended_by_an_error_leaves_no_signal_held_in_its_process",
    "study/test_shutdown.py::test_a_worker_whose_launcher_dies_ends_once_its_job_has_marked_its_run",
    "study/test_render.py::test_drain_takes_runs_from_the_back_of_the_queue_while_the_renderer_goes_on_from_the_front",
    "study/test_references.py::test_the_ranking_waits_for_a_referenced_run_until_it_ends",
    "study/test_references.py::test_the_wait_is_bounded_and_names_what_is_still_running",
    "study/test_store.py::test_a_store_left_half_made_by_an_older_version_is_repaired_and_the_launch_says_so",
    "study/test_store.py::test_a_full_disk_while_the_store_is_created_leaves_nothing_and_the_next_launch_works",
    "test_bench.py::test_a_page_is_stale_when_what_it_measured_changes_and_names_its_command",
    "study/test_cli.py::test_maglev_command_answers_a_missing_store_in_one_line",
    "study/test_cli.py::test_study_py_refuses_a_typo_with_the_key_and_creates_no_run",
    "study/test_hostile.py::test_a_tracking_uri_mlflow_cannot_use_is_refused_in_one_line",  # three processes
    "study/test_compose.py::test_every_job_of_the_lab_sweep_gets_hydras_own_config_from_one_composition_per_choice_of_groups",
    "study/test_cautions.py::test_ranking_and_report_follow_the_residual_tests_both_ways",
    "study/test_ranking.py::test_missing_store_unknown_and_empty_experiment_are_clear_errors",
    "study/test_ranking.py::test_ranking_twice_reuses_the_ranking_run_and_force_logs_a_new_one",
    "study/test_ranking.py::test_rank_cli_logs_the_ranking_run",
    "study/test_ranking.py::test_structure_option_and_its_errors",
    "structures/test_registry.py::test_toy_structure_runs_through_a_sweep_and_the_ranking",
    "study/test_sweeper.py::test_a_grid_sweep_runs_only_the_orders_it_adds_and_resumes",  # three tiny sweeps
    "test_bench.py::test_benchmark_script_runs",
    "test_layers.py::test_only_the_study_layer_reaches_hydra_omegaconf_or_mlflow",
    "test_layers.py::test_import_maglev_pulls_in_no_hydra_omegaconf_mlflow_or_matplotlib",
    "test_layers.py::test_identification_core_does_not_reach_matplotlib",  # fresh interpreters measure imports
    "test_layers.py::test_the_rules_see_a_heavy_import_through_a_library",
    "study/test_render.py::test_a_dead_renderer_fails_its_runs_and_abandon_kills_the_queued_ones",
    "study/test_render.py::test_drain_draws_the_runs_the_busy_renderer_has_not_started",
    "study/test_render.py::test_a_drawing_error_is_tagged_and_the_run_still_finishes",
    "study/test_render.py::test_a_server_gone_under_the_renderer_ends_the_sweep_with_its_one_line_and_the_renderer_says_nothing",
    "study/test_faults.py::test_a_server_gone_when_a_job_claims_its_config_ends_the_sweep_in_one_line_and_its_end_writes_nothing",
    "estimation/test_estimate.py::test_monte_carlo_spread_matches_reported_covariance",
    "sim/test_bla.py::test_blas_of_several_classes_are_the_estimates_bla_makes_one_class_at_a_time",
    "sim/test_bla.py::test_a_feature_narrower_than_a_welch_bin_counts_with_the_band_it_occupies",
    "sim/test_labdata.py::test_labdata_cli_writes_loadable_files",
    "sim/test_plant.py::test_batch_simulation_is_the_loop_over_records",
    "study/test_decisions.py::test_the_simulated_sweeps_datasets_are_the_record_rules_choice_from_the_simulated_lab_set",
    "study/test_render.py::test_lab_steps_queued_on_the_renderer_are_made_by_the_time_drain_returns_a_failure_a_warning",
    "study/test_hostile.py::test_a_sweep_tag_read_back_from_the_store_cannot_move_the_report",
    "study/test_store.py::test_a_new_store_is_mlflows_own_empty_store_copied_from_the_cache",
    "study/test_figures.py::test_a_runs_figures_drawn_on_another_runs_are_the_images_new_figures_give",
    "study/test_faults.py::test_rank_against_a_closed_port_says_so_in_one_line",
    "study/test_report_pdf.py::test_pages_before_the_appendix_heading_are_counted",
    "study/test_store.py::test_a_damaged_store_is_answered_in_one_line_by_every_command_and_a_sweep",
)


def listed(item: pytest.Item, names: tuple[str, ...]) -> bool:
    """Whether ``names`` (``SLOW``, ``SERVICE``) names the item's file or its test function."""
    try:
        path = item.path.relative_to(TESTS).as_posix()
    except ValueError:
        return False
    return path in names or f"{path}::{item.name.split('[')[0]}" in names


def pytest_configure(config: pytest.Config) -> None:
    if hasattr(config.option, "loadscopereorder"):  # pytest-xdist: keep the collection order below
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Files of ``LONGEST_FIRST`` first, in that order; the rest after them, as collected; ``SLOW`` marked slow;
    ``SERVICE`` marked service, and skipped unless ``MAGLEV_SERVICE=1``."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}

    def key(item: pytest.Item) -> int:
        try:
            return rank.get(item.path.relative_to(TESTS).as_posix(), len(rank))
        except ValueError:
            return len(rank)

    items.sort(key=key)
    service_stage = os.environ.get("MAGLEV_SERVICE") == "1"
    for item in items:
        if listed(item, SLOW):
            item.add_marker(pytest.mark.slow)
        if listed(item, SERVICE):
            item.add_marker(pytest.mark.service)
            if not service_stage:
                item.add_marker(SERVICE_SKIP)


@pytest.fixture
def refdata() -> Path:
    """The real recordings (``$MAGLEV_REFDATA`` or ``../shared/refdata``), or skip with the reason."""
    path = refdata_dir()
    if path is None or not (path / "el2820_maglev_2022").is_dir():
        searched = os.environ.get("MAGLEV_REFDATA") or REPO.parent / "shared" / "refdata"
        pytest.skip(f"real lab data not found at {searched} (set MAGLEV_REFDATA or place ../shared/refdata)")
    return path


@pytest.fixture(scope="session", autouse=True)
def settled_libraries() -> None:
    """In each pytest-xdist worker (the README's suite, the fast loop): the libraries its tests use imported
    first and frozen, as study.py does (:mod:`maglev.study.heap`), with full collections held off from this
    file's import, before the worker collects (0.8 s of full collections in a collection otherwise).  A worker
    holds ~0.4 M of their objects, which every full garbage collection walked again (0.2-0.3 s each, some 30
    per worker).  What the tests make after that and keep for the session (stores, cached records) grows to
    another 0.2-0.4 M objects, so a worker collects its full generation a tenth as often as Python's default:
    over a whole suite 14.6 s of collections in the two workers, 7.4 s so, with either worker's peak memory
    still under 0.8 GB."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    import control  # noqa: F401
    import hydra  # noqa: F401
    import mlflow.store.tracking.sqlalchemy_store  # noqa: F401
    import scipy.signal  # noqa: F401

    import maglev.study.callbacks  # noqa: F401
    import maglev.study.figures  # noqa: F401
    import maglev.study.job  # noqa: F401
    import maglev.study.report  # noqa: F401

    heap.settle()
    young, middle, _ = gc.get_threshold()
    gc.set_threshold(young, middle, 100)


@pytest.fixture(scope="session")
def migrated_db(tmp_path_factory) -> Path:
    """An empty MLflow SQLite store (tables only), created once per worker: MLflow's migrations of a fresh
    file take 0.6 s in a process that has run them before, 1.5–2 s in a new one (idle 2-core machine),
    which a test that is not about creating the store need not pay again."""
    from maglev.study.tracking import new_client

    path = tmp_path_factory.mktemp("migrated") / "mlflow.db"
    new_client(f"sqlite:///{path}")
    return path


@pytest.fixture
def migrated_store(tmp_path, migrated_db) -> Path:
    """``tmp_path`` holding a copy of the empty store as ``mlflow.db`` (what the harness's overrides use)."""
    shutil.copyfile(migrated_db, tmp_path / "mlflow.db")
    return tmp_path
