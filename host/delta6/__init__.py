"""Delta6: host software for the Delta6 6-axis force/torque sensing end-effector."""

__version__ = "0.1.0"
