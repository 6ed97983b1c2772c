"""Run dense linear algebra single-threaded inside the estimators and the ARX order search.

The estimators factorise tall, skinny matrices (N × 5…30) hundreds of times.  For
such shapes multi-threaded BLAS gains nothing and, on a machine with other work
(a parallel sweep, a second core busy), its threads contend: a 10 000 × 13 QR was
measured at 1.6 ms single-threaded and 9–40 ms with two OpenBLAS threads under
load.  ``single_threaded_blas`` limits BLAS to one thread for the duration of one
estimation, without touching the caller's settings elsewhere.  A study run uses it
too, so its metrics are bit-identical whether a joblib worker (where loky already
caps BLAS at one thread) or a plain process (``maglev reproduce``) computes them.
"""

from __future__ import annotations

import functools
from typing import Callable, TypeVar

from threadpoolctl import ThreadpoolController

F = TypeVar("F", bound=Callable)
_controller: ThreadpoolController | None = None


def single_threaded_blas(func: F) -> F:
    """Decorator: call ``func`` with BLAS limited to one thread."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        global _controller
        if _controller is None:
            _controller = ThreadpoolController()
        with _controller.limit(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
