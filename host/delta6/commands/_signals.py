"""Signals as the command line handles them: SIGTERM and SIGHUP end a command like Ctrl-C.

Every command ends on SIGINT, SIGTERM or SIGHUP with one line and the shell's status for that
signal (130, 143, 129), having closed what it opened. The streaming commands (``log``,
``stream``) take the signal as their normal end instead: they stop at the next block, keep
every sample received, and exit 0 (docs/reliability.md).
"""
from __future__ import annotations

import contextlib
import signal
import threading

#: The signals that end a command, where the platform has them.
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                     if hasattr(signal, name))


class Terminated(KeyboardInterrupt):
    """A stop signal other than SIGINT, raised like Ctrl-C's KeyboardInterrupt."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def exit_status(exc: KeyboardInterrupt) -> int:
    """The shell's status for a command ended by a signal: 128 + its number."""
    return 128 + getattr(exc, "signum", signal.SIGINT)


def signal_name(exc: KeyboardInterrupt) -> str:
    return signal.Signals(getattr(exc, "signum", signal.SIGINT)).name


def _raise(signum, _frame):
    raise Terminated(signum)


@contextlib.contextmanager
def terminate_like_interrupt():
    """SIGTERM and SIGHUP raise :class:`Terminated` (a KeyboardInterrupt) in the main thread,
    so everything that cleans up after Ctrl-C cleans up after them too."""
    with _handlers(_raise, [s for s in STOP_SIGNALS if s != signal.SIGINT]):
        yield


class StopRequest:
    """Set by a stop signal; ``signum`` says which. A second signal raises, as an escape
    from a shutdown that hangs."""

    def __init__(self):
        self.event = threading.Event()
        self.signum: int | None = None
        self._holding = False

    def is_set(self) -> bool:
        return self.event.is_set()

    def __call__(self, signum, _frame):
        if self.event.is_set() and not self._holding:
            raise Terminated(signum) if signum != signal.SIGINT else KeyboardInterrupt
        self.signum = self.signum or signum
        self.event.set()

    def hold(self) -> None:
        """From now on (until the handlers are restored), further signals only request the
        stop: what is being closed is closed whole (a quick second Ctrl-C left a log under its
        .partial name, or the device streaming with the capture cut)."""
        self._holding = True

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name if self.signum else ""


@contextlib.contextmanager
def stop_requests():
    """Within the block, a stop signal sets the :class:`StopRequest` it yields instead of
    raising: a streaming loop ends at its next check, never in the middle of a write."""
    request = StopRequest()
    with _handlers(request, STOP_SIGNALS):
        yield request


@contextlib.contextmanager
def _handlers(handler, signals):
    if threading.current_thread() is not threading.main_thread():
        yield                # only the main thread receives signals in Python
        return
    previous = {s: signal.signal(s, handler) for s in signals}
    try:
        yield
    finally:
        for s, old in previous.items():
            signal.signal(s, old)
