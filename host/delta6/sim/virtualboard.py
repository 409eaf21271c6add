"""The virtual board: the firmware's ATmega328P image running in simavr, with six emulated
ERCK-05SPI encoders on its pins and its UART on a pseudo-terminal (docs/virtual-board.md).

    with VirtualBoard(replay="run.csv") as board:        # or live=True, faults=[...]
        with Device(board.port) as dev:                  # any host tool works on board.port
            dev.start(250)
            ...
        print(board.stats()["timing"]["latency_cycles"])

The C harness (``tools/simavr/virtual_board/``) is built here with the host compiler and cached
under ``build/simavr/``; the firmware image comes from :mod:`delta6.build.appbuild`. Encoder angles
come from a replay file (a log with ``t`` and ``theta_e1..6``, converted here to raw counts)
and/or the live channel (:class:`LiveChannel`), which the digital twin can drive.
"""
from __future__ import annotations

import json
import math
import os
import signal
import socket
import struct
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

import numpy as np

from delta6.build import appbuild, avrbuild
from delta6.core.calibration import check_log_meta
from delta6.core.errors import UserError
from delta6.link.logfile import LogError, read_log
from delta6.link.protocol import DEFAULT_BAUD, theta_to_counts, valid_counts
from delta6.sim import avrsim

HARNESS_DIR = avrbuild.REPO_ROOT / "tools" / "simavr" / "virtual_board"
CONTRACT = avrbuild.FIRMWARE / "src" / "board_contract.h"
FAULT_KINDS = ("biterror", "weak", "strong", "noanswer")
EEPROM_SIZE = 1024
REPLAY_MAGIC = b"D6RP"
#: A replay count that is no count: the encoder does not answer at that sample (VB_NO_ANSWER).
NO_ANSWER = 0xFFFF


class VirtualBoardError(UserError):
    """The virtual board cannot be built or started, or its input is unusable."""


@dataclass(frozen=True)
class Fault:
    """Encoder ``encoder`` (1..6) fails with ``kind`` for frames latched in [start, stop) s of
    board time (``stop`` may be ``math.inf``)."""

    encoder: int
    kind: str
    start: float
    stop: float = math.inf

    def __post_init__(self):
        if not 1 <= self.encoder <= 6:
            raise VirtualBoardError(f"fault: encoder {self.encoder} is not 1..6")
        if self.kind not in FAULT_KINDS:
            raise VirtualBoardError(f"fault: kind {self.kind!r} is not one of "
                                    f"{', '.join(FAULT_KINDS)}")
        if not (self.start >= 0 and self.stop > self.start):
            raise VirtualBoardError(f"fault: window {self.start}..{self.stop} s is empty")

    @classmethod
    def parse(cls, spec: str) -> "Fault":
        """``E:KIND:T0:T1`` (T1 may be ``inf``), e.g. ``3:weak:1.0:1.5``."""
        parts = spec.split(":")
        if len(parts) != 4:
            raise VirtualBoardError(f"--fault takes E:KIND:T0:T1 (e.g. 3:weak:1.0:1.5), "
                                    f"got {spec!r}")
        try:
            return cls(int(parts[0]), parts[1], float(parts[2]), float(parts[3]))
        except ValueError:
            raise VirtualBoardError(f"--fault {spec!r}: encoder and times must be numbers") \
                from None

    def arg(self) -> str:
        stop = "inf" if math.isinf(self.stop) else repr(self.stop)
        return f"{self.encoder}:{self.kind}:{self.start!r}:{stop}"


# --- building ---------------------------------------------------------------------------------

def harness() -> Path:
    """The compiled harness (built on first use, rebuilt when a source changes)."""
    return avrsim.build_tool("delta6_vboard", sorted(HARNESS_DIR.glob("*.c")),
                             [*sorted(HARNESS_DIR.glob("*.h")), CONTRACT],
                             error=VirtualBoardError)


def firmware(design_include: Path | None = None, *, test_hooks: bool = False,
             defines=()) -> avrbuild.Image:
    """The application image the board runs (cached): the committed design header unless
    ``design_include`` names another generated-header directory."""
    extra = [*defines, *(["DELTA6_TEST_HOOKS"] if test_hooks else [])]
    name = "delta6-app-test" if test_hooks else "delta6-app"
    return appbuild.build_app(design_include, name=name, defines=extra)


# --- replay files -----------------------------------------------------------------------------

def write_replay(path: Path, t, counts) -> Path:
    """The harness's replay file: t (s, from 0, non-decreasing) and (n, 6) raw counts
    (:data:`NO_ANSWER` where that encoder fails its read)."""
    t = np.asarray(t, dtype="<f8")
    counts = np.asarray(counts)
    if t.ndim != 1 or counts.shape != (len(t), 6) or len(t) == 0:
        raise VirtualBoardError("a replay needs n time stamps and (n, 6) counts, n >= 1")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0) or t[0] < 0:
        raise VirtualBoardError("replay time stamps must be finite, from 0, non-decreasing")
    if not valid_counts(np.where(counts == NO_ANSWER, 0, counts), shape=None):
        raise VirtualBoardError("replay counts must be 0..16383 (or NO_ANSWER)")
    records = np.zeros(len(t), dtype=[("t", "<f8"), ("c", "<u2", (6,))])
    records["t"] = t
    records["c"] = counts
    with open(path, "wb") as f:
        f.write(REPLAY_MAGIC + struct.pack("<II", 1, len(t)))
        f.write(records.tobytes())
    return path


def replay_from_log(log_path: Path, out: Path, zero=0, design=None) -> tuple[Path, int]:
    """Convert a log (``t``, ``theta_e1..6``; ``docs/log-format.md``) into a replay file whose
    times start at 0. A missing angle (the log's failed read) is replayed as that encoder not
    answering: the board flags it as it did, never a made-up angle. Returns the path and the
    number of samples. With ``design`` (the firmware's), a log whose header names
    another design is refused: its angles come from another mechanism."""
    try:   # a log has samples and strictly increasing time, or read_log says why not
        data = read_log(log_path, require_complete_rows=False)
    except LogError as exc:
        raise VirtualBoardError(f"replay file: {exc}") from None
    if design is not None:
        try:
            check_log_meta(data.meta, design, source=f"replay file {log_path}")
        except UserError as exc:
            raise VirtualBoardError(str(exc)) from None   # (it says: pass --design)
    t, theta = np.asarray(data.t, dtype=float), np.asarray(data.theta, dtype=float)
    missing = ~np.isfinite(theta).all(axis=1)
    if missing.all():
        raise VirtualBoardError(f"replay file {log_path} has no complete row of theta_e1..6 "
                                "(a wrench-only log cannot drive the encoders)")
    failed = ~np.isfinite(theta)
    counts = theta_to_counts(np.where(failed, 0.0, theta), zero).astype(np.int64)
    counts[failed] = NO_ANSWER
    return write_replay(out, t - t[0], counts), len(t)


def demo_trajectory(duration_s: float = 20.0, rate_hz: float = 200.0,
                    amplitude: float = 0.35, limit_rad: float = math.pi / 6):
    """A smooth motion inside the joint box for the demo: each joint a sum of two sines of
    incommensurate frequencies, at ``amplitude`` of the joint limit. Returns (t, theta)."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    f1 = np.array([0.13, 0.17, 0.19, 0.23, 0.29, 0.31])
    f2 = np.array([0.41, 0.37, 0.53, 0.47, 0.59, 0.43])
    phase = np.arange(6) * 0.9
    theta = amplitude * limit_rad * (0.6 * np.sin(2 * np.pi * f1 * t[:, None] + phase)
                                     + 0.4 * np.sin(2 * np.pi * f2 * t[:, None] + 2 * phase))
    return t, theta


# --- the running board ----------------------------------------------------------------------

class VirtualBoard:
    """A running virtual board. ``port`` is the pty to open; the simulation starts when a
    client opens it (unless ``wait_for_client`` is False).

    ``replay``: a log file (``t``, ``theta_e1..6``) or an already converted ``.d6rp`` file;
    ``zero``: the counts the emulated mechanism reports at zero deflection (default 0, the
    firmware's uncalibrated zero); ``live``: open the live channel and connect to it
    (``self.live``), on a socket in a temporary directory, or at the path given (for another
    process to drive: ``self.live_path``);
    ``faults``: :class:`Fault` windows; ``eeprom``: an EEPROM image file kept across runs;
    ``speed``: 1.0 paces board time to the wall clock, 0 runs as fast as it can;
    ``duration``: board seconds to run; ``read_log``: write the encoder read log there;
    ``ram_dump``: the SRAM at the end (:func:`stack_depth` reads it).
    """

    def __init__(self, *, image: avrbuild.Image | None = None, replay: Path | None = None,
                 loop: bool = False, zero=0, live: bool | Path = False,
                 faults: Iterable[Fault] = (),
                 eeprom: Path | None = None, speed: float = 1.0,
                 duration: float | None = None, read_log: Path | None = None,
                 wait_for_client: bool = True, bus_timing_ns: tuple[int, int, int] | None = None,
                 baud: int = DEFAULT_BAUD, ram_dump: Path | None = None,
                 replay_design=None):
        self.image = image or firmware()
        self.replay = Path(replay) if replay else None
        self.replay_design = replay_design   # the firmware's design: a replay log must match
        self.loop = loop
        self.zero = np.broadcast_to(np.asarray(zero, dtype=np.int64), (6,)).copy()
        if not valid_counts(self.zero):
            raise VirtualBoardError("zero counts must be 0..16383")
        self.want_live = live
        self.faults = list(faults)
        self.eeprom = Path(eeprom) if eeprom else None
        self.speed = speed
        self.duration = duration
        self.read_log = Path(read_log) if read_log else None
        self.wait_for_client = wait_for_client
        self.bus_timing_ns = bus_timing_ns
        self.baud = baud
        self.ram_dump = Path(ram_dump) if ram_dump else None
        self.port: str | None = None
        self.live: LiveChannel | None = None
        self.live_path: Path | None = None
        self.stats_path: Path | None = None
        self.proc: subprocess.Popen | None = None
        self._tmp: tempfile.TemporaryDirectory | None = None
        self._stderr: list[str] = []

    # -- lifetime --

    def start(self) -> "VirtualBoard":
        try:
            return self._start()
        except BaseException:
            self.close()
            raise

    def _start(self) -> "VirtualBoard":
        exe = harness()
        self._tmp = tempfile.TemporaryDirectory(prefix="delta6-vboard-")
        tmp = Path(self._tmp.name)
        self.stats_path = tmp / "stats.json"
        # --parent: the emulator ends when this process is gone, however it ended.
        cmd = [str(exe), str(self.image.elf), "--freq", str(avrbuild.NANO.f_cpu),
               "--baud", str(self.baud), "--speed",
               repr(float(self.speed)), "--stats", str(self.stats_path),
               "--rest", ",".join(str(int(z)) for z in self.zero), "--parent", str(os.getpid())]
        if self.replay is not None:
            cmd += ["--replay", str(self._replay_file(tmp))]
            if self.loop:
                cmd.append("--loop")
        if self.want_live:
            self.live_path = (tmp / "live.sock" if self.want_live is True
                              else Path(self.want_live))
            cmd += ["--live", str(self.live_path)]
        for fault in self.faults:
            cmd += ["--fault", fault.arg()]
        if self.eeprom is not None:
            cmd += ["--eeprom", str(self.eeprom)]
        if self.duration is not None:
            cmd += ["--duration", repr(float(self.duration))]
        if self.read_log is not None:
            cmd += ["--read-log", str(self.read_log)]
        if not self.wait_for_client:
            cmd.append("--no-wait")
        if self.bus_timing_ns is not None:
            cmd += ["--bus-timing", ",".join(str(int(v)) for v in self.bus_timing_ns)]
        if self.ram_dump is not None:
            cmd += ["--ram-dump", str(self.ram_dump)]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        threading.Thread(target=self._drain_stderr, daemon=True).start()
        line = self.proc.stdout.readline()
        if not line.startswith("pty "):
            self.proc.wait(timeout=10)
            raise VirtualBoardError("the virtual board did not start: "
                                    + (self._error_text() or f"exit status {self.proc.returncode}"))
        self.port = line.split(" ", 1)[1].strip()
        if self.live_path is not None:
            self.live = LiveChannel(self.live_path, zero=self.zero)
        return self

    def _replay_file(self, tmp: Path) -> Path:
        if not self.replay.exists():
            raise VirtualBoardError(f"replay file {self.replay} not found")
        with open(self.replay, "rb") as f:
            if f.read(4) == REPLAY_MAGIC:
                return self.replay
        out, _ = replay_from_log(self.replay, tmp / "replay.d6rp", self.zero,
                                 design=self.replay_design)
        return out

    def _drain_stderr(self) -> None:
        for line in self.proc.stderr:
            self._stderr.append(line.rstrip("\n"))

    def _error_text(self) -> str:
        errors = [ln for ln in self._stderr if "error" in ln]
        return (errors or self._stderr or [""])[-1].replace("delta6_vboard: error: ", "")

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the board to end (``duration``); returns the exit status."""
        return self.proc.wait(timeout=timeout)

    def stop(self, timeout: float = 10.0) -> int:
        """End the run cleanly (SIGTERM: the client gets what is queued, the EEPROM and the
        statistics are saved). Returns the exit status."""
        if self.live is not None:
            self.live.close()
        if self.proc is None:
            return 0
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode

    def close(self) -> None:
        self.stop()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> "VirtualBoard":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    @property
    def stderr(self) -> str:
        return "\n".join(self._stderr)

    def stats(self) -> dict:
        """The final statistics (after :meth:`stop` or the end of ``duration``), or a live
        snapshot through the live channel while running."""
        if self.running and self.live is not None:
            return self.live.stats()
        if self.stats_path is None or not self.stats_path.exists():
            raise VirtualBoardError("no statistics: the board has not run to its end")
        return json.loads(self.stats_path.read_text())


def measure_stream(board: "VirtualBoard", dev, rate: int, seconds: float,
                   settle_s: float = 0.3) -> tuple[dict, int]:
    """Start ``dev`` (a Device on ``board``, a live board) streaming at ``rate``; after
    ``settle_s`` of board time, measure ``seconds`` of it, reading the stream all along.
    Returns the board's statistics over that window and the samples the host lost in it; the
    stream keeps running (the caller stops it)."""
    dev.start(rate)
    live = board.live
    settle_until = live.time() + settle_s
    while live.time() < settle_until:
        dev.flush()
        time.sleep(0.02)
    lost0 = dev.health.samples_lost
    live.reset_stats()
    end = live.time() + seconds
    while live.time() < end:
        dev.flush()
        time.sleep(0.02)
    return live.stats(), dev.health.samples_lost - lost0


def stack_depth(ram_dump: Path, static_ram: int, ram_start: int = 0x100) -> int:
    """Bytes of stack the firmware used at most, from a RAM dump of a run: simavr starts the
    SRAM zeroed, so the lowest non-zero byte above the static data (.data + .bss, which start
    at ``ram_start``) is as deep as the stack went (a lower bound, exact unless the deepest
    bytes pushed were all zero)."""
    ram = np.frombuffer(Path(ram_dump).read_bytes(), dtype=np.uint8)
    above = np.flatnonzero(ram[static_ram:])
    return 0 if len(above) == 0 else int(len(ram) - static_ram - above[0])


class LiveChannel:
    """The live channel of a running board (docs/virtual-board.md, "Live channel").

    ``set_theta(t, theta)`` / ``set_counts(t, counts)`` schedule what the encoders report from
    board time ``t`` (s; ``None``: now); ``fault`` / ``clear`` inject and remove faults;
    ``time()`` is the board's clock, ``stats()`` its statistics; ``drive(samples)`` feeds a
    stream of (t, theta) samples (e.g. :func:`delta6.twin.iter_realtime`), staying at most
    ``lead`` seconds ahead of the board."""

    def __init__(self, path: Path, zero=0, connect_timeout: float = 10.0):
        self.zero = zero
        deadline = time.monotonic() + connect_timeout
        while True:
            try:
                self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                self.sock.connect(str(path))
                break
            except OSError:
                self.sock.close()
                if time.monotonic() > deadline:
                    raise VirtualBoardError(f"cannot connect to the live channel {path}") \
                        from None
                time.sleep(0.02)
        self._file = self.sock.makefile("r", encoding="ascii", newline="\n")
        self._lock = threading.Lock()
        self.closed = False

    def close(self) -> None:
        self.closed = True
        try:
            self._file.close()
            self.sock.close()
        except OSError:
            pass

    def _send(self, line: str) -> None:
        try:
            self.sock.sendall(line.encode("ascii") + b"\n")
        except OSError as exc:
            raise VirtualBoardError(f"the live channel is gone: {exc}") from None

    def _query(self, line: str, answer: str) -> str:
        with self._lock:
            self._send(line)
            while True:
                reply = self._file.readline()
                if not reply:
                    raise VirtualBoardError("the live channel closed")
                reply = reply.rstrip("\n")
                if reply.startswith("error "):
                    raise VirtualBoardError(f"live channel: {reply[6:]}")
                if reply.startswith(answer):
                    return reply[len(answer):].strip()

    @staticmethod
    def _at(t: float | None) -> str:
        return "now" if t is None else repr(float(t))

    def set_counts(self, t: float | None, counts) -> None:
        values = [int(c) for c in counts]
        if not valid_counts(values):
            raise VirtualBoardError("counts are six integers 0..16383")
        self._send(f"counts {self._at(t)} " + " ".join(map(str, values)))

    def set_theta(self, t: float | None, theta) -> None:
        self.set_counts(t, theta_to_counts(theta, self.zero))

    def fault(self, encoder: int | str, kind: str, start: float | None = None,
              stop: float = math.inf) -> None:
        if kind not in FAULT_KINDS:
            raise VirtualBoardError(f"fault kind {kind!r} is not one of {', '.join(FAULT_KINDS)}")
        stop_text = "inf" if math.isinf(stop) else repr(float(stop))
        self._send(f"fault {encoder} {kind} {self._at(start)} {stop_text}")

    def clear(self, encoder: int | str = "all") -> None:
        self._send(f"clear {encoder}")

    def hang(self, on: bool) -> None:
        """Test builds: make the main loop hang (the watchdog must reset the board)."""
        self._send(f"hang {'on' if on else 'off'}")

    def time(self) -> float:
        """Board time, s. Answered after everything sent before it was applied."""
        return float(self._query("time", "time ").split()[0])

    def stats(self) -> dict:
        return json.loads(self._query("stats", "stats "))

    def reset_stats(self) -> None:
        self._query("stats-reset", "ok")

    def drive(self, samples, *, lead: float = 0.25, t0: float | None = None,
              stop: threading.Event | None = None) -> int:
        """Send every (t, theta) of ``samples`` as a timed update at board time
        ``t - t_first + t0`` (t0: the board's clock when the first sample arrives), never more
        than ``lead`` s ahead of the board. Returns the number of samples sent; ends quietly
        when ``stop`` is set or the channel is closed (the board stopped)."""
        sent = 0
        try:
            offset = None
            board_now = self.time()
            for sample in samples:
                if (stop is not None and stop.is_set()) or self.closed:
                    break
                t, theta = float(sample[0]), sample[1]
                if offset is None:
                    offset = (board_now if t0 is None else t0) - t
                at = t + offset
                while at - board_now > lead:
                    time.sleep(min(0.05, at - board_now - lead))
                    board_now = self.time()
                self.set_theta(at, theta)
                sent += 1
        except VirtualBoardError:
            if not self.closed:
                raise
        return sent
