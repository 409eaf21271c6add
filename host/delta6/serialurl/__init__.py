"""pyserial URL handlers of the delta6 package (``serial.protocol_handler_packages``).

``delta6sim://`` is a simulated Delta6 (:mod:`delta6.simdevice`): every ``--port`` option and
:class:`delta6.device.Device` accept it where a serial port name would go.
"""
import serial

PACKAGE = __name__


def register() -> None:
    """Make ``serial.serial_for_url`` find the handlers of this package (idempotent)."""
    if PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(PACKAGE)
