"""The units of the rig's signals, as every record, figure, logged dataset and report states them.

Kept apart from :mod:`maglev.plots` so that a run which draws nothing (writing a simulated record, logging a
dataset) does not import matplotlib for two strings.
"""

U_UNIT = "A"  # coil current
Y_UNIT = "cm"  # upper magnet height as the rig's calibrated sensor reports it
