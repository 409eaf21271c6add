"""Rolling plots of the six wrench axes in a terminal: one panel per axis, time to the right,
each column the range (min..max) of the samples that fell into it, so noise and spikes show
at any rate. Plain text: redrawn in place on a terminal, printed as frames otherwise."""
from __future__ import annotations

import numpy as np

from delta6.core.model import AXES

UNITS = ("N",) * 3 + ("N*m",) * 3
MARK, ZERO = "#", "-"


class RollingPlot:
    """The last ``seconds`` of samples, drawn ``width`` columns wide, ``height`` rows per axis."""

    def __init__(self, seconds: float = 5.0, width: int = 72, height: int = 4):
        if seconds <= 0 or width < 8 or height < 1:
            raise ValueError("a plot needs a positive span, at least 8 columns and 1 row")
        self.seconds, self.width, self.height = seconds, width, height
        self._t = np.empty(0)
        self._w = np.empty((0, 6))

    def add(self, t: np.ndarray, wrench: np.ndarray) -> None:
        """Append samples (device time, s; (n, 6) wrench); keep only the visible span."""
        self._t = np.concatenate((self._t, np.asarray(t, float)))
        self._w = np.concatenate((self._w, np.asarray(wrench, float).reshape(-1, 6)))
        keep = self._t > self._t[-1] - self.seconds if len(self._t) else slice(None)
        self._t, self._w = self._t[keep], self._w[keep]

    def columns(self, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """Per column, the min and max of the axis's finite samples in it (NaN: none)."""
        lo = np.full(self.width, np.nan)
        hi = np.full(self.width, np.nan)
        if not len(self._t):
            return lo, hi
        end = self._t[-1]
        col = np.floor((self._t - (end - self.seconds)) / self.seconds * self.width).astype(int)
        col = np.clip(col, 0, self.width - 1)
        v = self._w[:, axis]
        ok = np.isfinite(v)
        np.fmin.at(lo, col[ok], v[ok])
        np.fmax.at(hi, col[ok], v[ok])
        return lo, hi

    def panel(self, axis: int) -> list[str]:
        lo, hi = self.columns(axis)
        finite = np.isfinite(lo)
        if finite.any():
            bottom, top = float(np.min(lo[finite])), float(np.max(hi[finite]))
        else:
            bottom, top = -1.0, 1.0
        if top - bottom < 1e-9:                       # a flat line sits in the middle
            bottom, top = bottom - 0.5, top + 0.5
        step = (top - bottom) / self.height
        now = self._w[-1, axis] if len(self._t) else np.nan
        title = (f"{AXES[axis]} {now:+10.4f} {UNITS[axis]:<3}  range {bottom:+.4g} .. {top:+.4g}"
                 if np.isfinite(now) else f"{AXES[axis]}        nan {UNITS[axis]:<3}")
        rows = []
        for r in range(self.height):                  # top row first
            band_hi = top - r * step
            band_lo = band_hi - step
            marked = finite & (hi >= band_lo) & (lo <= band_hi)
            zero = band_lo <= 0.0 < band_hi or (r == self.height - 1 and band_lo == 0.0)
            fill = ZERO if zero else " "
            rows.append("|" + "".join(MARK if m else fill for m in marked) + "|")
        return [title] + rows

    def render(self) -> str:
        """All six panels, and the time span they show."""
        lines = []
        for axis in range(6):
            lines += self.panel(axis)
        lines.append(f"last {self.seconds:g} s of device time, newest on the right")
        return "\n".join(lines)
