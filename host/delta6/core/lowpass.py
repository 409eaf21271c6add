"""The device's low-pass filter in Python: the reference the firmware's float32 implementation
(``firmware/lib/delta6_core/src/delta6_filter.*``) is checked against, bit for bit.

A second-order Butterworth low-pass (the bilinear transform with the cutoff prewarped, as
``scipy.signal.butter(2, cutoff, fs=rate)``), run per axis as

    y[n] = y[n-1] + a2 (y[n-1] - y[n-2]) + c (s/4 - y[n-1]),   s = x[n] + 2 x[n-1] + x[n-2]

with ``c = 1 + a1 + a2``: the classic biquad rearranged so that float32 rounding acts on small
differences and the gain at DC is exactly 1; what the addition to y[n-1] rounds away is carried
into the next step (error feedback). The history starts filled with the first sample.
"""
from __future__ import annotations

import numpy as np

#: The accepted cutoff, as a fraction of the sample rate (the firmware's kMin/kMaxCutoffRatio).
MIN_CUTOFF_RATIO = 0.001
MAX_CUTOFF_RATIO = 0.45


def in_range(cutoff_hz: float, rate_hz: float) -> bool:
    f32 = np.float32
    return bool(rate_hz > 0 and f32(cutoff_hz) >= f32(MIN_CUTOFF_RATIO) * f32(rate_hz)
                and f32(cutoff_hz) <= f32(MAX_CUTOFF_RATIO) * f32(rate_hz))


def design(cutoff_hz: float, rate_hz: float) -> tuple[float, float]:
    """(c, a2) in float64 for ``cutoff_hz`` at ``rate_hz``."""
    if not in_range(cutoff_hz, rate_hz):
        raise ValueError(f"cutoff {cutoff_hz} Hz is outside {MIN_CUTOFF_RATIO} .. "
                         f"{MAX_CUTOFF_RATIO} x the rate {rate_hz} Hz")
    k = np.tan(np.pi * cutoff_hz / rate_hz)
    n = 1.0 / (1.0 + np.sqrt(2.0) * k + k * k)
    return 4.0 * k * k * n, (1.0 - np.sqrt(2.0) * k + k * k) * n


def transfer(c: float, a2: float) -> tuple[np.ndarray, np.ndarray]:
    """The classic (b, a) of the same filter, for scipy.signal.lfilter."""
    return np.array([c / 4, c / 2, c / 4]), np.array([1.0, c - 1.0 - a2, a2])


def run(x, c: float, a2: float) -> np.ndarray:
    """Filter (n, axes) samples in float32, operation for operation as the firmware does."""
    f32 = np.float32
    x = np.asarray(x, dtype=f32)
    c, a2, quarter = f32(c), f32(a2), f32(0.25)
    out = np.empty_like(x)
    x1 = x2 = y1 = y2 = x[0].copy()
    carry = np.zeros_like(x[0])
    for i in range(len(x)):
        xi = x[i]
        quarter_sum = quarter * ((xi + x1) + (x1 + x2))
        step = (a2 * (y1 - y2) + c * (quarter_sum - y1)) + carry
        y = y1 + step
        carry = step - (y - y1)
        x2, x1, y2, y1 = x1, xi, y1, y
        out[i] = y
    return out
