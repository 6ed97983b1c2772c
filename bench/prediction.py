"""What a k-step prediction costs as the horizon grows: CPU time and peak memory of ``PolyModel.predict``.

    python bench/prediction.py [--samples 20000 200000] [--repeats 3]

For a Box–Jenkins model (bj [2 1 1 2 1]) with its initial state estimated, predicts a record it simulates, of
each length at horizons 1, 50, N/2, N − 1 and 10**9 (simulation) and prints the median CPU time
(single-threaded BLAS) and the peak memory traced by ``tracemalloc``, in units of one N-sample
array.  The target: no horizon above a few N-sample arrays or a second of CPU, so time and
memory grow with N and not with k.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from maglev import IOData, PolyModel  # noqa: E402
from maglev.threads import single_threaded_blas  # noqa: E402

TARGET_ARRAYS = 40  # peak memory, in N-sample float64 arrays
TARGET_S = 1.0
MODEL = PolyModel(A=[1.0], B=[0, 1.0, 0.5], C=[1, 0.5], D=[1, -0.8], F=[1, -1.5, 0.7], nk=1, Ts=1e-3, structure="bj")


def record(n: int, seed: int) -> IOData:
    """n samples of the model driven by white noise, innovations of standard deviation 0.5."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    return IOData(u, MODEL.simulate(u, 0.5 * rng.standard_normal(n)), MODEL.Ts)


@single_threaded_blas
def measure(model, data, horizon: int, repeats: int) -> tuple[float, float]:
    """(median CPU seconds, peak traced bytes) of one ``predict(data, horizon, "estimate")``."""
    cpu = []
    for _ in range(repeats):
        tic = time.process_time()
        model.predict(data, horizon, "estimate")
        cpu.append(time.process_time() - tic)
    tracemalloc.start()
    try:
        model.predict(data, horizon, "estimate")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return statistics.median(cpu), peak


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--samples", type=int, nargs="+", default=[20_000, 200_000])
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args(argv)
    print(f"{'N':>8s}  {'horizon':>10s}  {'CPU s':>8s}  {'peak / N-array':>14s}")
    worst_s, worst_arrays = 0.0, 0.0
    for n in a.samples:
        data = record(n, seed=6)
        for k in (1, 50, n // 2, n - 1, 10**9):
            cpu, peak = measure(MODEL, data, k, a.repeats)
            arrays = peak / (8 * n)
            worst_s, worst_arrays = max(worst_s, cpu), max(worst_arrays, arrays)
            print(f"{n:8d}  {k:10d}  {cpu:8.3f}  {arrays:14.1f}")
    print(f"worst: {worst_s:.3f} s of CPU (target {TARGET_S:g} s), {worst_arrays:.1f} N-arrays "
          f"(target {TARGET_ARRAYS}): {'within' if worst_s < TARGET_S and worst_arrays < TARGET_ARRAYS else 'OVER'} "
          "target")
    return 0


if __name__ == "__main__":
    sys.exit(main())
