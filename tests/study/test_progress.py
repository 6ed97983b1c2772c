"""The time left that a sweep's run lines end with (maglev.study.progress), on a clock the test sets."""

from __future__ import annotations

import pytest

from maglev.study import progress


@pytest.fixture
def sweep(monkeypatch):
    """A sweep whose runs started at t = 1000 s; ``end(t)`` records a run ending at t (the test's clock)."""
    clock = {"now": 1000.0}
    monkeypatch.setattr(progress.time, "time", lambda: clock["now"])
    monkeypatch.setenv(progress.START_ENV, "1000.0")
    monkeypatch.setattr(progress, "_ran", {})

    def end(t: float) -> None:
        clock["now"] = t
        progress.run_done()

    return end


def test_the_estimate_is_the_mean_time_between_run_ends_after_the_first_times_the_jobs_left(sweep):
    sweep(1030.0)  # the first run also paid for the imports and the data: no estimate from it alone
    assert progress.time_left(0, 24, sequential=True) == "; 23 job(s) left"
    sweep(1034.0)
    sweep(1040.0)  # two intervals after the first run: 4 s and 6 s, 5 s per run
    assert progress.time_left(2, 24, sequential=True) == "; 21 job(s) left, ≈ 1 min 45 s"
    assert progress.time_left(23, 24, sequential=True) == "; the last job"


def test_without_a_sequential_launcher_or_a_size_there_is_no_estimate(sweep):
    sweep(1030.0)
    sweep(1034.0)
    assert progress.time_left(1, 24, sequential=False) == "; 22 job(s) left"  # joblib, submitit: runs overlap
    assert progress.time_left(1, None, sequential=True) == ""
    assert progress.time_left(None, 24, sequential=True) == ""


def test_a_new_sweep_in_the_same_process_starts_counting_again(sweep, monkeypatch):
    sweep(1030.0)
    sweep(1034.0)
    monkeypatch.setenv(progress.START_ENV, "2000.0")
    assert progress.time_left(1, 24, sequential=True) == "; 22 job(s) left"


@pytest.mark.parametrize("seconds, text", [(0.4, "0 s"), (59.4, "59 s"), (60, "1 min 00 s"), (205, "3 min 25 s"),
                                           (3600, "1 h 00 min"), (3900, "1 h 05 min")])
def test_durations_read_as_a_person_would_say_them(seconds, text):
    assert progress.duration(seconds) == text
