"""The learned estimator sample by sample: keeps the last window of readings and turns each new
sample into a wrench, the same numbers as :meth:`LearnedEstimator.predict` on the whole log.

With a device (``delta6.link.device``), stream raw counts (``set_mode("raw")``) and either wrap
its sample iterator or register a callback:

    live = LearnedEstimator("gru.onnx", design=design).streaming()
    live.check_device(dev.info())
    for sample, wrench in live.wrap(dev.samples()):
        ...
    remove = dev.on_sample(live.callback(lambda sample, wrench: ...))
"""
from __future__ import annotations

import copy
from typing import Callable, Iterable, Iterator

import numpy as np

from delta6.core.errors import UserError
from delta6.learning.windows import new_segment, window_index

NO_ANGLES = ("the stream carries no encoder angles: a learned estimator needs the raw counts "
             "(Device.set_mode(\"raw\"), delta6 stream --raw)")


class StreamingEstimator:
    def __init__(self, estimator):
        self.estimator = estimator
        self.window = estimator.window
        # Its own base: a calibrated base carries state from block to block, and two streams
        # on one estimator must not run each other's samples through it.
        self.base = copy.copy(estimator.base)
        self.base.reset()
        self._buffer = np.zeros((self.window, 6))
        self._last_t: float | None = None
        self._session = None

    def reset(self) -> None:
        """Forget the history: the next sample starts a new window (as after a gap)."""
        self._last_t = None
        self._session = None
        self.base.reset()

    def update(self, t: float, theta, session: int | None = None) -> np.ndarray:
        """The wrench (6,) for a new sample at time ``t`` (s) with encoder angles ``theta``
        (rad); NaN while the window holds a missing angle."""
        return self.update_block([t], np.asarray(theta, dtype=float).reshape(1, 6),
                                 None if session is None else [session])[0]

    def update_block(self, t, theta, session=None) -> np.ndarray:
        """The wrench (n, 6) for a block of samples ((n,) times, (n, 6) angles or None when the
        stream carried no counts), each row as if fed alone and in order: the block's windows
        in one network call and the base over the block (a stream at 250 Hz arrives in
        blocks, and a call per sample costs more than the model). ``session`` ((n,), the
        device's session of each sample, if the stream carries it): a new one starts a new
        window, like a step back in time."""
        if theta is None:
            raise UserError(NO_ANGLES)
        t = np.asarray(t, dtype=float).reshape(-1)
        theta = np.asarray(theta, dtype=float).reshape(-1, 6)
        n, w = len(t), self.window
        if n == 0:
            return np.zeros((0, 6))
        # The window before the block (its last w - 1 readings), then the block; a step longer
        # than the gap, or back in time, starts a new segment, whose window repeats its first
        # reading (as in the batch: windows.new_segment).
        rows = np.vstack([self._buffer[1:], theta])
        rate = self.estimator.rate_hz
        brk = np.zeros(len(rows), dtype=bool)
        brk[0] = True
        brk[w - 1] = self._last_t is None or bool(new_segment(t[0] - self._last_t, rate))
        brk[w:] = new_segment(np.diff(t), rate)
        if session is not None:
            session = np.asarray(session).reshape(-1)
            brk[w - 1] |= self._session is not None and session[0] != self._session
            brk[w:] |= session[1:] != session[:-1]
            self._session = session[-1]
        starts = np.maximum.accumulate(np.where(brk, np.arange(len(rows)), 0))
        win = rows[window_index(starts, w)[w - 1:]]
        self._buffer = win[-1].copy()
        self._last_t = float(t[-1])
        base = self.base.update_block(t, theta)
        out = np.full((n, 6), np.nan)
        ok = np.isfinite(win).all(axis=(1, 2))
        if ok.any():
            norm = self.estimator.card.norm
            out[ok] = norm.wrench(self.estimator.network(norm.inputs(win[ok]))) + base[ok]
        return out

    # -- with a Device ------------------------------------------------------------------------

    def check_device(self, info) -> None:
        """Refuse a device that runs another design (``info``: ``Device.info()``)."""
        card = self.estimator.card
        if info.design_hash != card.design_hash:
            raise UserError(f"{self.estimator.path} was trained for design {card.design_name} "
                            f"(0x{card.design_hash:08x}); the device runs {info.design_name} "
                            f"(0x{info.design_hash:08x})")

    def wrench_of(self, sample) -> np.ndarray:
        if sample.theta is None:
            raise UserError(NO_ANGLES)
        return self.update(sample.t, sample.theta, sample.session)

    def wrap(self, samples: Iterable) -> Iterator[tuple[object, np.ndarray]]:
        """``(sample, learned wrench)`` for each device sample."""
        for sample in samples:
            yield sample, self.wrench_of(sample)

    def callback(self, handler: Callable[[object, np.ndarray], None]) -> Callable[[object], None]:
        """A ``Device.on_sample`` callback that calls ``handler(sample, learned wrench)``."""
        def on_sample(sample) -> None:
            handler(sample, self.wrench_of(sample))
        return on_sample
