"""Delta6: host software for the Delta6 6-axis force/torque sensing end-effector.

Layers, lowest first (``docs/architecture.md``; import-linter enforces the direction):
``core`` (reference model, designs), ``link`` (protocol, device, log format), ``build``
(compilers), ``sim`` (simulated device, virtual board), ``twin``, ``diagnosis``, ``calibration``,
``learning``, ``evaluation``, ``commands``.
"""
import serial

__version__ = "0.1.0"

# pyserial finds URL handlers by package name and imports them only when such a URL is opened,
# so ``delta6sim://`` works everywhere a port name does without the device layer depending on
# the simulator.
_URL_HANDLERS = "delta6.sim.serialurl"
if _URL_HANDLERS not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(_URL_HANDLERS)
