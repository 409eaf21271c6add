"""Learned estimators. ``mcu``: the small integer residual model the microcontroller runs."""
