"""``python -m maglev``: the ``maglev`` command (:mod:`maglev.study.cli`)."""

from maglev.study.cli import main

raise SystemExit(main())
