"""The host side of a Delta6: a serial port (or any pyserial URL) speaking the protocol.

    with Device("/dev/ttyACM0") as dev:        # or "delta6sim://", "socket://host:port"
        print(dev.info().design_name)
        dev.start(200)                           # Hz (up to 350; 200 with an on-chip model)
        dev.tare(200)
        for sample in dev:                       # or dev.on_sample(callback), dev.latest()
            print(sample.t, sample.wrench)

A reader thread decodes the stream as it arrives; samples wait in a bounded queue (the oldest
are dropped, and counted, if nobody reads them). Commands carry request ids, are answered
while streaming goes on, and are retried on timeout; the device answers a retry without
running the command twice. Every loss is counted in :attr:`Device.health`.
"""
from __future__ import annotations

import collections
import contextlib
import os
import random
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Callable, Iterator

import numpy as np
import serial

from delta6.core.design import MAX_RATE_HZ
from delta6.core.errors import UserError
from delta6.link import protocol as P
from delta6.link.decoder import DecoderStats, SequenceTracker, StreamDecoder
from delta6.link.infocheck import info_problem
from delta6.link.protocol import DEFAULT_BAUD

# pyserial finds URL handlers by package name and imports them only when such a URL is opened,
# so ``delta6sim://`` works everywhere a port name does without this layer importing the
# simulator. Registered here, where ports are opened, not at package import: ``import delta6``
# (the console script's first step, before it handles Ctrl-C) stays free of pyserial.
_URL_HANDLERS = "delta6.sim.serialurl"
if _URL_HANDLERS not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(_URL_HANDLERS)

#: Commands after whose answer the records mean something else (mode, rate, tare, zero).
STREAM_CHANGING = frozenset({P.Command.START, P.Command.SET_MODE, P.Command.TARE,
                             P.Command.CLEAR_TARE, P.Command.SET_ZERO, P.Command.ZERO_HERE,
                             P.Command.LOAD_DEFAULTS})
#: Commands that only ask: sending one again to a device that restarted meanwhile is harmless.
QUESTIONS = frozenset({P.Command.GET_INFO, P.Command.PING, P.Command.GET_TELEMETRY})


class DeviceError(UserError):
    """Talking to the device failed; the message names the port and the problem."""


class PortLost(DeviceError):
    """The port went away (cable unplugged, device reset the USB link)."""


class CommandTimeout(DeviceError):
    """A command was not answered after all retries."""


class CommandRejected(DeviceError):
    """The device answered NACK; ``nack`` holds its reason."""

    def __init__(self, message: str, nack: P.Nack):
        super().__init__(message)
        self.nack = nack


class DeviceRestarted(DeviceError):
    """The device restarted (a BOOT event, another boot id) while a command or a sequence of
    commands was under way: what it had been told is gone, so nothing is sent on."""


class ProtocolMismatch(DeviceError):
    """The device speaks an incompatible protocol version."""


class CaptureFailed(DeviceError):
    """The capture file could not take the bytes received (a full disk)."""


class SampleTimeout(DeviceError):
    """No sample arrived in time."""


@dataclass(slots=True)
class Sample:
    t: float                 # device time, s (unwrapped, since the device started)
    host_t: float            # host time.monotonic() when the bytes arrived, s
    seq: int                 # unwrapped sequence number
    status: int              # status word (protocol.Status)
    wrench: np.ndarray       # Fx Fy Fz (N), Mx My Mz (N*m) in frame {E}; NaN if invalid
    counts: np.ndarray | None = None   # raw encoder counts (wrench + raw mode)
    theta: np.ndarray | None = None    # encoder angles theta_e (rad), from counts and zero
    session: int = 0         # device session: counts up when the device restarted

    @property
    def flags(self) -> P.Status:
        return P.Status(self.status)

    @property
    def valid(self) -> bool:
        return not self.status & P.Status.WRENCH_INVALID


@dataclass
class SampleBlock:
    """Many samples as arrays (what :meth:`Device.read_block` returns)."""

    t: np.ndarray
    host_t: np.ndarray
    seq: np.ndarray
    status: np.ndarray
    wrench: np.ndarray           # (n, 6)
    theta: np.ndarray | None     # (n, 6), NaN rows where no counts were sent
    session: np.ndarray | None = None   # (n,) device session of each sample

    def __len__(self) -> int:
        return len(self.t)

    def head(self, n: int) -> "SampleBlock":
        """The first ``n`` samples."""
        return SampleBlock(self.t[:n], self.host_t[:n], self.seq[:n], self.status[:n],
                           self.wrench[:n], None if self.theta is None else self.theta[:n],
                           None if self.session is None else self.session[:n])


@dataclass
class Health:
    """Every loss and fault the host saw, plus the device's latest telemetry."""

    decoder: DecoderStats
    samples: int = 0
    sequence_gaps: int = 0
    samples_lost: int = 0
    duplicates: int = 0
    queue_drops: int = 0
    callback_errors: int = 0
    device_resets: int = 0   # BOOT events seen
    restarts: int = 0        # new sessions seen without a BOOT event (counters, boot id)
    stale_dropped: int = 0   # samples queued before a command changed what they mean
    impossible_counts: int = 0   # raw counts beyond 0..16383: left empty like a failed read
    commands: int = 0
    command_retries: int = 0
    telemetry: P.Telemetry | None = field(default=None)

    def as_dict(self) -> dict:
        d = asdict(self)
        d["telemetry"] = self.telemetry._asdict() if self.telemetry else None
        return d

    def summary(self) -> str:
        return (f"{self.samples} samples, {self.samples_lost} lost in {self.sequence_gaps} gaps, "
                + self.link_summary())

    def link_summary(self) -> str:
        """The losses on the way (decoder, queue), then the device's own if it reported any."""
        text = (f"{self.decoder.errors} bad frames, {self.decoder.bytes_discarded} bytes "
                f"discarded, {self.queue_drops} queue drops")
        if self.impossible_counts:
            text += f", {self.impossible_counts} impossible encoder counts left empty"
        if self.telemetry is not None:
            t = self.telemetry
            text += (f"; device: {t.overruns} overruns, {t.tx_dropped} tx drops, "
                     f"{sum(t.encoder_errors)} encoder errors")
        return text


class _Pending:
    __slots__ = ("command", "event", "response")

    def __init__(self, command: int):
        self.command = command
        self.event = threading.Event()
        self.response = None


class Device:
    """A Delta6 on ``port``: a serial device name or any pyserial URL (``delta6sim://``,
    ``socket://host:port``, ``loop://``).

    ``timeout`` (s) bounds each command attempt; ``retries`` repeats it. ``handshake`` asks
    for the device info on open (turn it off only for a port that is not a device, e.g. to
    replay recorded frames over ``loop://``). ``capture`` is a new file (an existing one is
    refused: two sessions in one capture would be decoded as one) or a binary file object to
    which every received byte is written (``delta6 decode`` reads it). ``exclusive`` locks a
    serial port so that a second program cannot open it and steal its bytes ("port busy").
    """

    def __init__(self, port: str, *, baud: int = DEFAULT_BAUD, timeout: float = 0.5,
                 retries: int = 2, queue_size: int = 100_000, handshake: bool = True,
                 capture=None, exclusive: bool = True):
        self.port = port
        self.baud = baud
        self.timeout = timeout
        self.retries = retries
        self.queue_size = queue_size
        self.handshake = handshake
        self.exclusive = exclusive
        self._capture_target = capture
        self._capture = None
        self._serial = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._cond = threading.Condition()
        self._command_lock = threading.Lock()
        self._write_lock = threading.Lock()
        self._queue: collections.deque = collections.deque()
        self._latest = None
        self._pending: dict[int, _Pending] = {}
        self._request_id = random.randrange(1, 256)   # a new session never repeats the last id
        self._callbacks: list[Callable[[Sample], None]] = []
        self._decoder = StreamDecoder()
        self._tracker = SequenceTracker()
        self._health = Health(decoder=self._decoder.stats)
        self._info: P.Info | None = None
        self._boot_id: int | None = None      # the device's boot session (protocol 1.1)
        self._boots = 0                       # restarts seen (BOOT events, boot id changes)
        self._guard: tuple[str, int] | None = None   # (what, self._boots at its start)
        self._lsb: np.ndarray | None = None       # self._info.lsb, parsed once per info
        self._failure: DeviceError | None = None
        self._started = False
        self.callback_error: BaseException | None = None
        self.events: list[P.Event] = []

    # -- lifetime ----------------------------------------------------------------------

    def open(self) -> "Device":
        if self._serial is not None:
            return self
        self._stop.clear()
        self._failure = None
        self._decoder = StreamDecoder()          # every session counts afresh
        self._tracker = SequenceTracker()
        self._boot_id = None
        self._guard = None
        self._health = Health(decoder=self._decoder.stats)
        try:
            self._serial = serial.serial_for_url(self.port, baudrate=self.baud, timeout=0.05,
                                                 write_timeout=2.0,
                                                 exclusive=self.exclusive or None)
        except (serial.SerialException, OSError, ValueError) as exc:
            if "exclusively lock" in str(exc):
                raise DeviceError(f"port busy: {self.port} is open in another program "
                                  "(another delta6 log or stream?)") from None
            raise DeviceError(f"cannot open {self.port}: {_reason(exc)}") from None
        target = self._capture_target
        if isinstance(target, (str, os.PathLike)):
            try:
                # Unbuffered: every byte read is in the file at once, even if we are killed.
                self._capture = open(target, "xb", buffering=0)
            except FileExistsError:
                self._serial.close()
                raise DeviceError(f"the capture {target} exists: a capture holds one session "
                                  "(remove it or choose another name)") from None
            except OSError as exc:
                self._serial.close()
                raise DeviceError(f"cannot write the capture {target}: {exc.strerror}") from None
        elif target is not None:
            self._capture = target            # a binary file object of the caller's
        try:
            self._serial.reset_input_buffer()
        except (serial.SerialException, OSError):
            pass
        self._thread = threading.Thread(target=self._reader, name=f"delta6 reader {self.port}",
                                        daemon=True)
        self._thread.start()
        if self.handshake:
            try:
                self.info(refresh=True)
            except DeviceError:
                self.close()
                raise
        return self

    def close(self) -> None:
        """Stop the stream if this session started it, then release the port."""
        if self._serial is None:
            return
        if self._started and self._failure is None:
            try:
                self.stop()
            except DeviceError:
                pass
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        try:
            self._serial.close()
        except (serial.SerialException, OSError):
            pass
        self._serial = None
        if self._capture is not None:
            try:
                self._capture.flush()
                if self._capture is not self._capture_target:
                    self._capture.close()
            except OSError:
                pass            # a failed write already ended the session with its reason
            self._capture = None

    def __enter__(self) -> "Device":
        return self.open()

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "open" if self._serial is not None else "closed"
        return f"Device({self.port!r}, {state})"

    # -- commands ----------------------------------------------------------------------

    def info(self, refresh: bool = False) -> P.Info:
        """The device info record (identity, scaling, rate, mode, zero counts, tare)."""
        if refresh or self._info is None:
            info = self._request(P.Command.GET_INFO)
            problem = info_problem(info)
            if problem is not None:
                kind = ProtocolMismatch if info.protocol[0] != P.VERSION[0] else DeviceError
                raise kind(f"{self.port} sent an unusable device-info record: {problem}")
        return self._info

    def ping(self) -> tuple[float, int]:
        """(round-trip time in s, device clock in us when it answered)."""
        t0 = time.monotonic()
        ack = self._request(P.Command.PING)
        return time.monotonic() - t0, ack.value

    def start(self, rate_hz: int | None = None) -> int:
        """Start streaming at ``rate_hz`` (default: the configured rate); returns the rate."""
        if rate_hz is not None and not 1 <= rate_hz <= MAX_RATE_HZ:
            raise DeviceError(f"rate must be 1..{MAX_RATE_HZ} Hz, got {rate_hz}")
        ack = self._request(P.Command.START, rate_hz or 0)
        self._started = True
        self._update_info(rate_hz=ack.value, streaming=True)
        return ack.value

    def stop(self) -> None:
        """Stop the stream. Sent once (with its retries) even when unanswered: close() does
        not send it again to a device that no longer hears the host."""
        try:
            self._request(P.Command.STOP)
        finally:
            self._started = False
        self._update_info(streaming=False)

    def set_mode(self, mode: P.Mode | str) -> None:
        """``"wrench"`` or ``"raw"`` (wrench plus the six raw encoder counts)."""
        if isinstance(mode, str):
            names = {"wrench": P.Mode.WRENCH, "raw": P.Mode.WRENCH_RAW,
                     "wrench+raw": P.Mode.WRENCH_RAW}
            if mode not in names:
                raise DeviceError(f"mode is 'wrench' or 'raw', got {mode!r}")
            mode = names[mode]
        self._request(P.Command.SET_MODE, int(mode))
        self._update_info(mode=int(mode))

    def tare(self, samples: int = 100) -> np.ndarray:
        """Average ``samples`` samples on the device and subtract the mean from then on.
        Returns the offsets (N, N*m). Fails if a sample during averaging is flagged."""
        if not 1 <= samples <= 0xFFFF:
            raise DeviceError(f"tare takes 1..65535 samples, got {samples}")
        self._averaging(P.Command.TARE, samples)
        return np.array(self.info(refresh=True).tare)

    def clear_tare(self) -> None:
        self._request(P.Command.CLEAR_TARE)
        self.info(refresh=True)

    def zero_here(self, samples: int = 100) -> tuple:
        """Take the current encoder positions (averaged) as zero deflection. Clears the tare.
        Only with no load on the tool. Returns the new zero counts."""
        if not 1 <= samples <= 0xFFFF:
            raise DeviceError(f"zero capture takes 1..65535 samples, got {samples}")
        self._averaging(P.Command.ZERO_HERE, samples)
        return self.info(refresh=True).zero_counts

    def abort(self) -> bool:
        """Stop a tare or zero capture that is averaging (its command is answered NACK
        ABORTED, nothing changes). Returns whether one was running. Protocol 1.1."""
        info = self._require_info()
        if tuple(info.protocol) < (1, 1):
            raise DeviceError(f"{self.port} speaks protocol {info.protocol_version}, which has "
                              "no abort command (update the firmware)")
        return bool(self._request(P.Command.ABORT).value)

    def _averaging(self, command: P.Command, samples: int) -> None:
        """A tare or zero capture; if it is interrupted (Ctrl-C, a signal, no answer in time)
        the device is told to stop averaging, instead of staying busy for minutes."""
        try:
            self._request(command, samples, timeout=self._averaging_timeout(samples))
        except (KeyboardInterrupt, CommandTimeout):
            if self._failure is None and self._info is not None \
                    and tuple(self._info.protocol) >= (1, 1):
                try:
                    self._request(P.Command.ABORT)
                except DeviceError:
                    pass
            raise

    def set_zero(self, counts) -> None:
        counts = [int(c) for c in counts]
        if not P.valid_counts(counts):
            raise DeviceError("zero counts are six integers 0..16383")
        self._request(P.Command.SET_ZERO, *counts)
        self.info(refresh=True)

    def save_config(self) -> None:
        """Write rate, mode, tare, zero counts, filter, tool frame and limits to the device's
        EEPROM (a 1.0 device: the first four)."""
        self._request(P.Command.SAVE_CONFIG, timeout=max(self.timeout, 1.0))
        self.info(refresh=True)

    def load_defaults(self) -> None:
        """Factory configuration in RAM (save_config makes it permanent)."""
        self._request(P.Command.LOAD_DEFAULTS)
        self.info(refresh=True)

    def set_filter(self, cutoff_hz: float | None) -> float:
        """Low-pass the wrench on the device (second-order Butterworth at ``cutoff_hz``; None
        or 0: off). The cutoff must lie within 0.001 .. 0.45 x the sample rate. Returns the
        cutoff in use."""
        cutoff = 0.0 if cutoff_hz is None else float(cutoff_hz)
        if not np.isfinite(cutoff) or cutoff < 0:
            raise DeviceError(f"filter cutoff must be a positive number of Hz or 0 (off), "
                              f"got {cutoff_hz}")
        self._request_since(P.Command.SET_FILTER, cutoff)
        return self.info(refresh=True).filter_hz

    def set_tool(self, translation=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> None:
        """Report the wrench at the tool point ``translation`` (x, y, z in {E}, m) in axes
        rotated by ``rpy`` (roll, pitch, yaw about {E}, rad). No arguments: the identity.
        An active tare keeps its physical meaning (the device re-expresses it)."""
        values = np.asarray([*translation, *rpy], dtype=float)
        if values.shape != (6,) or not np.isfinite(values).all():
            raise DeviceError("the tool frame is three translations (m) and three angles (rad)")
        if (np.abs(values[:3]).max() > P.TOOL_MAX_TRANSLATION_M
                or np.abs(values[3:]).max() > P.TOOL_MAX_ANGLE_RAD):
            raise DeviceError(f"the tool point must lie within {P.TOOL_MAX_TRANSLATION_M:g} m "
                              "of the sensor frame's origin per axis, the angles within +-2 pi "
                              "rad")
        self._request_since(P.Command.SET_TOOL, *values)
        self.info(refresh=True)

    def set_limits(self, limits) -> np.ndarray:
        """Overload thresholds per axis in N and N*m (Fx Fy Fz Mx My Mz; None, 0 or NaN: no
        limit): a sample whose value on an axis exceeds its limit is flagged OVERRANGE. The
        device compares in counts of each axis's LSB; returns the limits as set, in N and
        N*m (NaN: none)."""
        counts = limit_counts(limits, self._require_info().lsb)
        self._request_since(P.Command.SET_LIMITS, *counts)
        return self.info(refresh=True).limit_values

    def telemetry(self) -> P.Telemetry:
        return self._request(P.Command.GET_TELEMETRY)

    @contextlib.contextmanager
    def restart_guard(self, what: str):
        """Commands that belong together (set, check, save): a restart of the device during
        the block raises :class:`DeviceRestarted` at the next command, or at the end, instead
        of going on with a device that forgot the first ones."""
        if self._guard is not None:         # nested: the outer block decides
            yield
            return
        self._guard = (what, self._boots)
        try:
            yield
            self._check_guard()
        finally:
            self._guard = None

    # -- samples -----------------------------------------------------------------------

    def __iter__(self) -> Iterator[Sample]:
        return self.samples()

    def samples(self, timeout: float | None = None) -> Iterator[Sample]:
        """Samples in order, forever; raises PortLost after the last sample received before
        the port went away, SampleTimeout if none arrives within ``timeout``."""
        while True:
            yield self.get(timeout)

    def get(self, timeout: float | None = None) -> Sample:
        item = self._take(1, timeout)[0]
        return self._sample(item)

    def read_block(self, max_samples: int | None = None,
                   timeout: float | None = None) -> SampleBlock:
        """Everything queued (at most ``max_samples``), waiting up to ``timeout`` for one."""
        items = self._take(max_samples or self.queue_size, timeout)
        info = self._require_info()
        t_us, host_t, seq, status, w, counts, session = zip(*items)
        status = np.array(status, dtype=np.int64)
        wrench = P.wrench_values(np.array(w, dtype=np.int64), status, self._lsb)
        theta = None
        if any(c is not None for c in counts):
            theta = P.theta_values(P.raw_counts(counts), status, info.zero_counts)
        return SampleBlock(t=np.array(t_us, dtype=np.int64) / 1e6, host_t=np.array(host_t),
                           seq=np.array(seq, dtype=np.int64), status=status, wrench=wrench,
                           theta=theta, session=np.array(session, dtype=np.int64))

    def latest(self) -> Sample | None:
        """The newest sample received (whether or not it was read from the queue)."""
        item = self._latest
        return None if item is None else self._sample(item)

    def flush(self) -> int:
        """Discard queued samples; returns how many."""
        with self._cond:
            n = len(self._queue)
            self._queue.clear()
        return n

    def on_sample(self, callback: Callable[[Sample], None]) -> Callable[[], None]:
        """Call ``callback(sample)`` from the reader thread for every sample (in addition to
        the queue). Keep it short; it must not send commands. Returns a function that removes
        it. Exceptions are counted in health.callback_errors and kept in callback_error."""
        self._callbacks.append(callback)
        return lambda: self._callbacks.remove(callback) if callback in self._callbacks else None

    @property
    def reboots(self) -> int:
        """Restarts the device confirmed (BOOT events, a new boot id); a session that began
        only because the counters stopped following on is not one."""
        return self._boots

    @property
    def health(self) -> Health:
        """A snapshot of the counters."""
        with self._cond:
            h = Health(**{**self._health.__dict__, "decoder": DecoderStats(
                **self._decoder.stats.as_dict())})
            h.sequence_gaps = self._tracker.gaps
            h.samples_lost = self._tracker.lost
            h.duplicates = self._tracker.duplicates
            h.restarts += self._tracker.restarts
        return h

    @property
    def failure(self) -> DeviceError | None:
        """Why the port stopped working, if it did."""
        return self._failure

    # -- internals ---------------------------------------------------------------------

    def _averaging_timeout(self, samples: int) -> float:
        rate = self._require_info().rate_hz or 1
        return self.timeout + 1.5 * samples / rate

    def _require_info(self) -> P.Info:
        if self._info is None:
            raise DeviceError(f"no device info from {self.port} yet: the wrench scale is unknown")
        return self._info

    def _update_info(self, **changes) -> None:
        if self._info is not None:
            self._set_info(self._info._replace(**changes))

    def _set_info(self, info: P.Info) -> None:
        # The scale first: whoever sees the new info (another thread) sees its scale too.
        self._lsb = info.lsb
        self._info = info
        if info.max_rate_hz:      # bounds how many records a gap can hide
            self._tracker.max_rate_hz = info.max_rate_hz

    def _request_since(self, command: P.Command, *args):
        """A command a device has only from a protocol minor version on: refused here, in one
        line, when the device is older (it would answer UNKNOWN_COMMAND)."""
        info = self.info()
        since = P.COMMAND_SINCE.get(command, (1, 0))
        if tuple(info.protocol) < since:
            raise DeviceError(
                f"{command.name.lower().replace('_', ' ')}: the device on {self.port} speaks "
                f"protocol {info.protocol_version}, the command needs "
                f"{'.'.join(map(str, since))}: update the firmware")
        return self._request(command, *args)

    def _restarted_during(self, what: str) -> DeviceRestarted:
        if self._guard is not None:
            what = self._guard[0]           # the sequence the command was part of
        return DeviceRestarted(f"the device on {self.port} restarted during {what}: its "
                               "settings since are lost; run the command again")

    def _check_guard(self) -> None:
        if self._guard is not None and self._guard[1] != self._boots:
            raise self._restarted_during(self._guard[0])

    def _next_request_id(self) -> int:
        self._request_id = self._request_id % 255 + 1    # 1..255; 0 means unsolicited
        return self._request_id

    def _request(self, command: P.Command, *args, timeout: float | None = None):
        if self._serial is None:
            raise DeviceError(f"{self.port} is not open")
        if threading.current_thread() is self._thread:
            raise RuntimeError("commands cannot be sent from a sample callback")
        name = command.name.lower().replace("_", " ")
        timeout = self.timeout if timeout is None else timeout
        with self._command_lock:
            self._raise_failure()
            self._check_guard()
            request_id = self._next_request_id()
            pending = _Pending(command)
            with self._cond:
                # Registered as the restarts are counted (the reader counts them under this
                # lock): a restart before is the device this command goes to, one after wakes
                # it. Apart, a restart between the two made an answered command fail.
                self._pending[request_id] = pending
                boots = self._boots
            frame = P.encode_command(command, request_id, *args)
            try:
                for attempt in range(self.retries + 1):
                    self._health.commands += attempt == 0
                    self._health.command_retries += attempt > 0
                    self._write(frame)
                    if pending.event.wait(timeout) and pending.response is not None:
                        break
                    self._raise_failure()
                    if self._boots != boots and command not in QUESTIONS:
                        # Never sent again to the fresh device (a second TARE, say): what
                        # the first one was part of is gone.
                        raise self._restarted_during(name)
                else:
                    tries = self.retries + 1
                    hint = (" (is a Delta6 connected at this baud rate?)"
                            if self._info is None else "")
                    raise CommandTimeout(f"{name}: no answer from {self.port} in {tries} "
                                         f"tries of {timeout:g} s{hint}")
            finally:
                self._pending.pop(request_id, None)
            self._raise_failure()
            if self._boots != boots and command not in QUESTIONS:
                raise self._restarted_during(name)     # answered, then forgotten
            self._check_guard()
        response = pending.response
        if isinstance(response, P.Nack):
            raise CommandRejected(f"{name} rejected by the device: {response.text()}", response)
        return response

    def _write(self, data: bytes) -> None:
        try:
            with self._write_lock:
                self._serial.write(data)
        except (serial.SerialException, OSError) as exc:
            self._fail(PortLost(f"lost the device on {self.port}: {_reason(exc)}"))
            self._raise_failure()

    def _raise_failure(self) -> None:
        if self._failure is not None:
            raise self._failure

    def _fail(self, error: DeviceError) -> None:
        with self._cond:
            if self._failure is None:
                self._failure = error
            for pending in self._pending.values():
                pending.event.set()
            self._cond.notify_all()

    def _reader(self) -> None:
        ser = self._serial
        while not self._stop.is_set():
            try:
                waiting = ser.in_waiting
                data = ser.read(waiting if waiting else 1)
            except Exception as exc:  # noqa: BLE001 - any failure of the port ends the stream
                if not self._stop.is_set():
                    self._fail(PortLost(f"lost the device on {self.port}: {_reason(exc)}"))
                return
            if not data:
                continue
            host_t = time.monotonic()
            if self._capture is not None:
                try:
                    self._capture.write(data)
                except (OSError, ValueError) as exc:
                    self._fail(CaptureFailed(f"cannot write the capture on {self.port}: "
                                             f"{getattr(exc, 'strerror', None) or exc}"))
                    return
            records = self._decoder.feed(data)
            if records:
                self._dispatch(records, host_t)

    def _dispatch(self, records: list, host_t: float) -> None:
        fresh = []
        with self._cond:
            for r in records:
                if isinstance(r, P.WrenchRecord):
                    unwrapped = self._tracker.update(r.seq, r.time_us)
                    if unwrapped is None:
                        continue
                    item = (unwrapped[1], host_t, unwrapped[0], r.status, r.wrench, r.counts,
                            self._tracker.session)
                    if len(self._queue) >= self.queue_size:
                        self._queue.popleft()
                        self._health.queue_drops += 1
                    self._queue.append(item)
                    self._latest = item
                    self._health.samples += 1
                    if r.counts is not None and max(r.counts) >= P.COUNTS_PER_TURN:
                        self._health.impossible_counts += sum(
                            c >= P.COUNTS_PER_TURN for c in r.counts)
                    if self._callbacks:
                        fresh.append(item)
                elif isinstance(r, (P.Ack, P.Nack)):
                    answered = self._resolve(r.request_id, r.command, r)
                    if answered and isinstance(r, P.Ack) and r.command in STREAM_CHANGING:
                        # The device sends answers and records in order: every record before
                        # this answer predates the command. Never hand those out as new.
                        self._health.stale_dropped += len(self._queue)
                        self._queue.clear()
                        self._latest = None
                elif isinstance(r, P.Info):
                    if info_problem(r) is None:     # never scale samples with a bad record
                        self._set_info(r)
                    self._note_boot(r.boot_id)
                    self._resolve(r.request_id, P.Command.GET_INFO, r)
                elif isinstance(r, P.Telemetry):
                    self._health.telemetry = r
                    self._note_boot(r.boot_id)
                    self._resolve(r.request_id, P.Command.GET_TELEMETRY, r)
                elif isinstance(r, P.Event):
                    self.events.append(r)
                    if r.code == P.EventCode.BOOT:
                        self._health.device_resets += 1
                        self._tracker.reset()
                        self._note_restart()
            self._cond.notify_all()
        for item in fresh:
            self._call_back(item)

    def _resolve(self, request_id: int, command: int, response) -> bool:
        """Hand ``response`` to the command waiting for it; whether one was."""
        pending = self._pending.get(request_id)
        if request_id and pending is not None and pending.command == command:
            pending.response = response
            pending.event.set()
            return True
        return False

    def _note_boot(self, boot_id: int | None) -> None:
        """A boot id other than the last one seen: the device restarted (its BOOT event may
        have been lost), so the records from here on are a new session."""
        if boot_id is None:
            return
        if self._boot_id is not None and boot_id != self._boot_id:
            if self._tracker.in_session:                # not already reset by a BOOT event
                self._health.restarts += 1
                self._tracker.reset()
            self._note_restart()
        self._boot_id = boot_id

    def _note_restart(self) -> None:
        """Wake the commands waiting for an answer that will not come from a fresh device
        (called with ``_cond`` held)."""
        self._boots += 1
        for pending in self._pending.values():
            if pending.command not in QUESTIONS:
                pending.event.set()

    def _call_back(self, item) -> None:
        if self._info is None:
            return
        sample = self._sample(item)
        for callback in list(self._callbacks):
            try:
                callback(sample)
            except Exception as exc:  # noqa: BLE001 - a user callback must not kill the reader
                self._health.callback_errors += 1
                self.callback_error = exc

    def _take(self, n: int, timeout: float | None) -> list:
        if timeout is None:
            rate = self._info.rate_hz if self._info else 1
            timeout = max(1.0, 20.0 / max(rate, 1))
        deadline = time.monotonic() + timeout
        with self._cond:
            while not self._queue:
                if self._failure is not None:
                    raise self._failure
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise SampleTimeout(f"no sample from {self.port} for {timeout:g} s "
                                        "(is the stream started?)")
                self._cond.wait(remaining)
            count = min(n, len(self._queue))
            return [self._queue.popleft() for _ in range(count)]

    def _sample(self, item) -> Sample:
        info = self._require_info()
        t_us, host_t, seq, status, w, counts, session = item
        wrench = P.wrench_values(np.array(w, dtype=np.int64)[None], np.array([status]),
                                 self._lsb)[0]
        raw = theta = None
        if counts is not None:
            raw = np.array(counts)
            theta = P.theta_values(raw[None], np.array([status]), info.zero_counts)[0]
        # t_us / 1e6, not * 1e-6: the double nearest the decimal (0.014, not 0.01399...).
        return Sample(t=t_us / 1e6, host_t=host_t, seq=seq, status=status, wrench=wrench,
                      counts=raw, theta=theta, session=session)


def limit_counts(limits, lsb) -> list[int]:
    """Overload limits in N and N*m (None, 0 or NaN: none) -> the device's counts of each
    axis's LSB, rounded to the nearest count (at least 1 for a positive limit)."""
    values = np.array([np.nan if v is None else float(v) for v in limits], dtype=float)
    if values.shape != (6,):
        raise DeviceError(f"six overload limits (Fx Fy Fz Mx My Mz), got {len(values)}")
    none = np.isnan(values) | (values == 0)
    if (values[~none] < 0).any() or np.isinf(values).any():
        raise DeviceError("overload limits are positive numbers (N, N*m), or 0 for none")
    counts = np.where(none, 0, np.maximum(1, np.round(np.where(none, 0, values) / lsb)))
    if (counts > P.MAX_VALUE).any():
        axis = int(np.argmax(counts > P.MAX_VALUE))
        raise DeviceError(f"overload limit {values[axis]:g} on axis {axis + 1} is beyond the "
                          f"wire's range ({P.MAX_VALUE * lsb[axis]:g})")
    return [int(c) for c in counts]


def _reason(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
