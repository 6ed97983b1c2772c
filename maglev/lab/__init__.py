"""The lab's steps before identification (EL2820 Lab 3 §3.1–3.4), one module each.

* :mod:`~maglev.lab.signals`        the input signals: staircase, step, uniform noise, random binary
* :mod:`~maglev.lab.averages`       ``get_average`` / ``get_stationary_averages`` (preparation tasks 2–3)
* :mod:`~maglev.lab.working_region` §3.1 the working region from a staircase
* :mod:`~maglev.lab.sampling`       §3.2 rise time → sampling period and decimation
* :mod:`~maglev.lab.input_design`   §3.4 the output's energy band → the binary signal's α*
* :mod:`~maglev.lab.plots`          their figures (the only module here that imports matplotlib)

Each step takes arrays or an ``IOData`` and returns a small frozen result; the study
logs them once per sweep (:mod:`maglev.study.lab`).
"""
