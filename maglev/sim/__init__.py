"""The simulated levitator and what is computed from it.

:mod:`.plant` (the nonlinear two-magnet model, calibrated to the rig), :mod:`.labdata`
(the lab's records simulated from it: staircase, white-noise and binary experiments),
:mod:`.bla` (the best linear approximation for an input class: the truth a linear
model of this plant is scored against), :mod:`.sim_vs_real` (the checks that compare it
with the real recordings) and :mod:`.calibrate` (fitting its parameters to them).
"""
