"""Delta6: host software for the Delta6 6-axis force/torque sensing end-effector.

Layers, lowest first (``docs/architecture.md``; import-linter enforces the direction):
``core`` (reference model, designs), ``link`` (protocol, device, log format), ``build``
(compilers), ``sim`` (simulated device, virtual board), ``twin``, ``diagnosis``, ``calibration``,
``learning``, ``evaluation``, ``commands``.
"""
__version__ = "0.1.0"
