"""History features of the encoder signals: play states, smoothed velocities, dwell ramps."""
from __future__ import annotations

import numpy as np

from delta6.core.operators import first_order, play


def play_state(x: np.ndarray, radii, y0=None) -> np.ndarray:
    """Normalised play state (x - play_r(x)) / r in [-1, 1] for every column of ``x`` (n, j)
    and every radius: shape (n, j, len(radii)). +1 after rising by at least 2r, -1 after
    falling by at least 2r, in between along the way. Each play starts centred on x[0], or
    continues from the play outputs ``y0`` (j, len(radii)) of the sample before x[0]."""
    return (np.asarray(x, dtype=float)[:, :, None] - play_output(x, radii, y0)) \
        / np.asarray(radii, dtype=float)


def play_output(x: np.ndarray, radii, y0=None) -> np.ndarray:
    """The play operators' outputs themselves, (n, j, len(radii)) (the state to carry on)."""
    x = np.asarray(x, dtype=float)[:, :, None]
    radii = np.asarray(radii, dtype=float)
    return play(x, radii, x[0] if y0 is None else y0)


def lagged(x: np.ndarray, t: np.ndarray, tau: float, *, step: float | None = None,
           y0=None) -> np.ndarray:
    """First-order lag of ``x`` with time constant ``tau``, started settled (or continuing
    from the output ``y0`` of the sample before x[0]). Logs are sampled uniformly (up to
    jitter): one pole, from the median ``step`` (default: of ``t``)."""
    step = np.median(np.diff(t)) if step is None else step
    return first_order(x, np.exp(-step / tau), y0)


#: Half-width of the window of the velocity's default local fit, s (the diagnosis lets each
#: log choose its own, ``terms.friction_velocity_window``). On a calibration rig's motion
#: (moves of seconds, dither of a few tenths of a hertz to about a hertz) the slope of a cubic
#: over +-0.2 s averages the 14-bit quantization of 21 samples at 50 Hz: about 0.7 mrad/s of
#: error against 1.8 with a line over +-2 samples, which a friction's smooth sign (a few
#: mrad/s wide) needs around each reversal; a faster motion needs a shorter window.
VELOCITY_HALF_WINDOW_S = 0.2
#: Degree of that local fit (a cubic: a symmetric window's slope is then exact up to the
#: fourth power of time).
VELOCITY_FIT_DEGREE = 3
#: Below this many samples either side (logs slower than 25 Hz) a cubic's slope is noisier
#: than a line's over two samples either side (noise gains 0.34 at 4, 0.25 at 5, against
#: 0.32), and the default falls back to that line.
VELOCITY_MIN_CUBIC_HALF = 5


def smooth_velocity(x: np.ndarray, t: np.ndarray, half_width: int | None = None,
                    step: float | None = None, degree: int = VELOCITY_FIT_DEGREE) -> np.ndarray:
    """d x / dt by a local polynomial fit of ``degree`` over 2*half_width+1 samples
    (suppresses the quantization noise of central differences of 14-bit angles); default
    width: :data:`VELOCITY_HALF_WINDOW_S` either side, or a line over two samples either side
    where that window holds fewer than :data:`VELOCITY_MIN_CUBIC_HALF` (slow logs). ``step``:
    the log's median sample step (default: of ``t``). The first and last ``half_width``
    samples take central differences."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    dt = np.median(np.diff(t)) if step is None else step
    if half_width is None:
        half_width = int(round(VELOCITY_HALF_WINDOW_S / dt)) if dt > 0 else 0
        if half_width < VELOCITY_MIN_CUBIC_HALF:
            half_width, degree = 2, 1
    if half_width < 1 or degree < 1:
        raise ValueError(f"a velocity needs a half width and a degree of at least 1, got "
                         f"{half_width} and {degree}")
    if n < 2 * half_width + 1:
        return np.gradient(x, t, axis=0)
    k = np.arange(-half_width, half_width + 1, dtype=float)
    # The slope at the centre of the least-squares polynomial through the window.
    weights = np.linalg.pinv(np.vander(k, min(degree, 2 * half_width) + 1, increasing=True))[1]
    # One column at a time: a long log's velocity takes one (n, j) array and one (n,)
    # temporary, not a shifted copy of the whole log per weight.
    vel = np.zeros_like(x)
    inner = slice(half_width, n - half_width)
    for j in range(x.shape[1]):
        vel[inner, j] = np.convolve(x[:, j], weights[::-1], mode="valid")
        vel[:, j] /= dt
        # The ends by central differences (np.gradient of the whole column: whether it takes
        # the grid as uniform depends on all of ``t``).
        edge = np.gradient(x[:, j], t)
        vel[:half_width, j] = edge[:half_width]
        vel[-half_width:, j] = edge[-half_width:]
    return vel


def dwell_ramps(x: np.ndarray, state: np.ndarray, t: np.ndarray, max_dwell_s: float,
                still: float, power: float = 1.0) -> np.ndarray:
    """``state`` (a direction of motion in [-1, 1], per column of ``x``) with each reversal
    placed where lost motion puts it: spread over the dwell before the encoder moved again.

    With play between a link and its encoder, a reversal first shows as the encoder standing
    still while the link turns through the play, and only then as motion the other way. Offline
    we can look ahead: before each sign change of ``state``, find the stretch where ``x`` stood
    at its turning value (within ``still``), ramp the state linearly across it from the old
    direction to the new one (over at most ``max_dwell_s``: a long hold is not all dwell), and
    take the new direction as reached from the first move onward. ``power`` shapes the ramp:
    1 is linear in time; 2 is a link that starts the dwell at rest at its turning point and
    accelerates away (the travel grows with the square of the time).
    """
    x = np.asarray(x, dtype=float)
    out = np.array(state, dtype=float, copy=True)
    for j in range(x.shape[1]):
        xs, d = x[:, j], out[:, j]
        sign = np.sign(state[:, j])
        for s in np.nonzero(sign[1:] * sign[:-1] < 0)[0] + 1:
            new = sign[s]
            # Back from the switch over the first moves the new way and the dwell, up to the
            # last step that still went the old way.
            i = s
            while i > 0 and new * (xs[i] - xs[i - 1]) >= -still:
                i -= 1
            turn = xs[i]
            end = i
            while end + 1 < s and abs(xs[end + 1] - turn) <= still:
                end += 1
            start = max(i, int(np.searchsorted(t, t[end] - max_dwell_s)))
            frac = np.linspace(0.0, 1.0, end - start + 2)[:-1] ** power
            d[start:end + 1] = -new + 2.0 * new * frac
            d[end + 1:s] = new
    return out


def moving_average(x: np.ndarray, half: int) -> np.ndarray:
    """Centred mean of each column of ``x`` (n, j) over 2*half+1 samples (fewer at the ends)."""
    n = len(x)
    total = np.zeros((n + 1,) + x.shape[1:])
    np.cumsum(x, axis=0, out=total[1:])
    idx = np.arange(n)
    lo, hi = np.maximum(idx - half, 0), np.minimum(idx + half + 1, n)
    return (total[hi] - total[lo]) / (hi - lo).reshape((n,) + (1,) * (x.ndim - 1))
