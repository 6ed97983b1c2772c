"""Entry point of the declarative study (Hydra app; one job = one MLflow run).

    python study.py                                        # one run: conf/config.yaml defaults
    python study.py dataset=binary_a025 structure=bj structure.order=3
    python study.py -m +sweep=lab                     # the lab sweep (39 runs)
    python study.py -m +sweep=lab hydra/launcher=parallel

The work is in ``maglev.study`` (see docs/tracking.md for what every run logs).
"""

import os
import warnings

from maglev.study import heap

heap.hold()  # no full garbage collection while the libraries are imported: settled once they are (maglev.study.heap)
os.environ["MPLBACKEND"] = "Agg"  # figures are files; importing matplotlib here would cost every launch 0.2 s
warnings.filterwarnings("ignore", message="The .*noload.* loader strategy is deprecated")

import hydra  # noqa: E402
from omegaconf import DictConfig  # noqa: E402

import maglev.study.schema  # noqa: E402,F401  (registers the schemas and ${maglev.root:})


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def main(cfg: DictConfig) -> float | None:
    from maglev.study.job import run

    return run(cfg)


if __name__ == "__main__":
    import atexit

    from maglev.study import shutdown

    shutdown.install(forward=True)  # SIGTERM (Slurm, kill): runs KILLED, nothing left RUNNING
    atexit.register(shutdown.skip_teardown)  # the last thing at exit: no interpreter teardown to wait for
    atexit.register(shutdown.final_line)  # registered before the sweep's handlers, so it runs after its end
    with shutdown.ending():
        try:
            main()
            shutdown.raise_if_received()  # held since the last job, with no sweep callback to raise it
        except KeyboardInterrupt:  # Ctrl-C: the sweep's line says what it ended; no traceback
            raise SystemExit(130) from None
