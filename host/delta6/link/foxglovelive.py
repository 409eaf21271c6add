"""The live stream for the Foxglove app: a WebSocket server (Foxglove's SDK) publishing the same
ROS 2 topics as the MCAP log (:mod:`delta6.link.ros2msg`) as samples arrive.

    with FoxgloveLive(port=8765) as live:        # Foxglove: Open connection, ws://localhost:8765
        for block in ...: live.publish(block)     # a SampleBlock from Device.read_block()

Message log times are the host's receive time as UNIX time; header stamps are the device's clock.
"""
from __future__ import annotations

import time

import numpy as np

from delta6.core.errors import UserError
from delta6.link import ros2msg as R
from delta6.link.mcaplog import DIAGNOSTICS_PERIOD, log_times

DEFAULT_PORT = 8765
#: The columns of the live /delta6/sample array (after t).
LIVE_EXTRA = ("t", "seq", "status", "host_t")


class FoxgloveLive:
    """Serve samples on ``host:port`` (port 0: any free port; see :attr:`port`)."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 frame_id: str = R.DEFAULT_FRAME_ID, hardware_id: str = ""):
        import foxglove
        self._context = foxglove.Context()        # our channels only, gone with this object
        self._channels = {
            topic: foxglove.Channel(topic, message_encoding="cdr", context=self._context,
                                    schema=foxglove.Schema(name=datatype, encoding="ros2msg",
                                                           data=R.definition(datatype).encode()))
            for topic, datatype in R.TOPICS.items()}
        self._messages = R.SampleMessages(frame_id, LIVE_EXTRA)
        self._diagnostics = R.DiagnosticsWindow(frame_id, hardware_id, DIAGNOSTICS_PERIOD)
        self.clock_offset = time.time() - time.monotonic()    # host_t is time.monotonic()
        self.published = 0
        try:
            self._server = foxglove.start_server(name="delta6", host=host, port=port,
                                                 context=self._context)
        except Exception as exc:      # the SDK's error for a taken port or a bad host
            for channel in self._channels.values():
                channel.close()
            raise UserError(f"cannot serve Foxglove on {host}:{port}: {exc}") from None

    @property
    def port(self) -> int:
        return self._server.port

    @property
    def url(self) -> str:
        return f"ws://localhost:{self.port}"

    def publish(self, block) -> None:
        """Send a block of samples (``t``, ``host_t``, ``seq``, ``status``, ``wrench``,
        ``theta``: a :class:`~delta6.link.device.SampleBlock`)."""
        n = len(block.t)
        if n == 0:
            return
        theta = block.theta if block.theta is not None else np.full((n, 6), np.nan)
        extra = np.stack([block.t, block.seq, block.status, block.host_t], axis=1).astype(float)
        log_time = log_times(block.t, block.host_t, self.clock_offset)
        for row, topic, data in self._messages.encode(block.t, theta, block.wrench, extra):
            self._channels[topic].log(data, log_time=int(log_time[row]))
        for lt, data in self._diagnostics.add(block.t, block.status, log_time):
            self._channels[R.TOPIC_STATUS].log(data, log_time=lt)
        self.published += n

    def close(self) -> None:
        self._server.stop()
        for channel in self._channels.values():
            channel.close()

    def __enter__(self) -> "FoxgloveLive":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
