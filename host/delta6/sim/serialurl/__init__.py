"""pyserial URL handlers of the delta6 package (``serial.protocol_handler_packages``).

``delta6sim://`` is a simulated Delta6 (:mod:`delta6.sim.simdevice`): every ``--port`` option and
:class:`delta6.link.device.Device` accept it where a serial port name would go. The package
``delta6`` registers this package's name with pyserial when it is imported.
"""
