"""The on-chip residual network in integers: the numpy reference of
``firmware/lib/delta6_core/src/delta6_residual.cpp``, equal to it integer for integer.

A residual model corrects the wrench a base model (the calibrated or the analytical model)
computes on the board. Per sample it takes two int16 vectors, the base wrench in input steps
(see below) and the six signed encoder count deltas, and returns six int16, the
correction in output steps (``output_step``). In between everything is integer:

The base wrench enters as ``round(wrench * input_scale)`` and the correction leaves as
``correction * output_step`` (float32, per axis).

1. **Features** (groups of six, each an int8 vector): the base wrench, the counts, their steps
   over one or two model periods (``wrench_step``, ``count_step``: value now minus value one
   period ago, or one period ago minus two), and play operators on the counts (``play``:
   x - play_r(x), r whole counts; rate-independent memory of the direction and extent of the
   last motion). Each value is saturated to int16 and requantized to int8 [-127, 127].
2. **Dense layers**: int8 weights, int32 bias and accumulation, requantized per output by a
   fixed-point multiplier m (Q15, 2^14 <= m < 2^15) and a shift s:
   ``round(acc * m / 2^s)`` (halves up), then ReLU to int8 [0, 127] (hidden layers) or
   saturation to int16 (the last layer: the correction).

History (the step features, the plays) is state. The model was trained at ``rate_hz``; a board
sampling at rate R looks back ``stride = max(1, round(R / rate_hz))`` of its samples per model
period, so a model period always spans the same time (exactly when R is a multiple of the
model's rate). A sample without a base wrench (encoder or solver fault) resets the state: the
next valid sample starts as if the device had been at rest there (every past value equal to it,
every play centred on it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from delta6.core.design import MAX_RATE_HZ
from delta6.core.operators import play

INT8_MAX = 127
INT16_MIN, INT16_MAX = -32768, 32767
#: A multiplier is Q15 and normalised: MULT_MIN <= m < MULT_LIMIT.
MULT_MIN, MULT_LIMIT = 1 << 14, 1 << 15
#: Shifts the C requantization supports exactly (32 x 16 bit product, no 64-bit arithmetic).
FEATURE_SHIFTS = (1, 30)     # int16 inputs: the product fits 31 bits
LAYER_SHIFTS = (16, 46)      # int32 accumulators
#: The board looks back at most this many samples per model period (400 Hz for a 50 Hz model).
MAX_STRIDE = 8
MAX_WIDTH = 48               # widest layer input or output (stack buffers on the board)
MAX_PLAY_RADIUS = 2000       # counts
#: Input steps per N (N*m) of base wrench a model may scale by (trained models: 16384 / full
#: scale, a few hundred to some ten thousands for the shipped designs).
INPUT_SCALE_RANGE = (1e-9, 1e9)
#: The correction's int16 range may span at most this many input ranges of the base wrench
#: (32767 / input_scale, twice the full scale for trained models). The quantizer sizes it as
#: OUTPUT_HEADROOM (4) times the largest correction; a log's wrench reads up to 3 full scales,
#: so a correction (reference minus base) stays below 6 full scales = 3 input ranges: 12 at
#: most, 64 with margin. Beyond it float32 corrections approach nonsense and then inf.
MAX_OUTPUT_RANGES = 64
#: Feature kinds and their codes in the generated header (delta6::residual::FeatureKind).
FEATURE_KINDS = {"wrench": 1, "counts": 2, "wrench_step": 3, "count_step": 4, "play": 5}
#: Kinds without a parameter: their param is 0.
PLAIN_KINDS = ("wrench", "counts")
STEP_KINDS = ("wrench_step", "count_step")


def requantize(acc, multiplier, shift):
    """round(acc * multiplier / 2^shift) with halves rounded up (towards +inf), exactly, as
    int64: the C code gets the same integer from 32-bit arithmetic."""
    acc = np.asarray(acc, dtype=np.int64)
    m = np.asarray(multiplier, dtype=np.int64)
    s = np.asarray(shift, dtype=np.int64)
    return (acc * m + (np.int64(1) << (s - 1))) >> s


def saturate(x, lo: int, hi: int) -> np.ndarray:
    return np.clip(np.asarray(x, dtype=np.int64), lo, hi)


def quantize_multiplier(real: float, shifts: tuple[int, int] = LAYER_SHIFTS) -> tuple[int, int]:
    """(m, s) with m / 2^s the closest such number to ``real`` > 0, 2^14 <= m < 2^15 and s in
    ``shifts``. Raises ValueError if ``real`` is outside what that range can represent."""
    real = float(real)
    if not np.isfinite(real) or real <= 0.0:
        raise ValueError(f"a requantization multiplier must be positive and finite, got {real}")
    mantissa, exponent = np.frexp(real)          # real = mantissa * 2^exponent, 0.5 <= mantissa < 1
    m = int(np.floor(mantissa * MULT_LIMIT + 0.5))
    s = 15 - int(exponent)
    if m == MULT_LIMIT:                           # rounded up to the next power of two
        m, s = MULT_MIN, s - 1
    if not shifts[0] <= s <= shifts[1]:
        raise ValueError(f"multiplier {real:.6g} needs shift {s}, outside {shifts[0]}..{shifts[1]}")
    return m, s


@dataclass(frozen=True)
class Feature:
    """One group of six features: ``kind`` (FEATURE_KINDS), ``param`` (play radius in counts;
    the period index k of a step: value k-1 periods ago minus value k periods ago), and the
    int16 -> int8 requantization per element."""

    kind: str
    param: int
    multiplier: tuple[int, ...]   # (6,)
    shift: tuple[int, ...]        # (6,)


@dataclass(frozen=True)
class Layer:
    weights: np.ndarray      # (out, in) int8
    bias: np.ndarray         # (out,) int32
    multiplier: np.ndarray   # (out,) int16, Q15
    shift: np.ndarray        # (out,) uint8
    relu: bool               # hidden layer (int8 ReLU) or the output layer (int16)

    @property
    def shape(self) -> tuple[int, int]:
        return self.weights.shape


@dataclass(frozen=True)
class Int8Net:
    rate_hz: float
    input_scale: np.ndarray   # (6,) float32: input steps per N (N*m) of base wrench
    output_step: np.ndarray   # (6,) float32: correction LSB
    features: tuple[Feature, ...]
    layers: tuple[Layer, ...]

    @property
    def inputs(self) -> int:
        return 6 * len(self.features)

    @property
    def macs(self) -> int:
        return sum(layer.weights.size for layer in self.layers)

    def max_lag(self, kind: str) -> int:
        """Periods of history a step feature of ``kind`` needs (0: none)."""
        return max((f.param for f in self.features if f.kind == kind), default=0)

    def play_radii(self) -> list[int]:
        return [f.param for f in self.features if f.kind == "play"]

    def history_length(self) -> int:
        """Ring entries the board keeps per history source: the deepest lag at MAX_STRIDE."""
        return history_length(self.features)

    def check(self) -> "Int8Net":
        """Raise ValueError unless the C engine can run this network exactly."""
        if not self.features or not self.layers:
            raise ValueError("a network needs at least one feature group and one layer")
        rate = float(self.rate_hz)
        if not (rate.is_integer() and 1 <= rate <= MAX_RATE_HZ):
            # the header carries it as a uint16_t: whole Hz, as the board's rates
            raise ValueError(f"rate_hz must be a whole number of Hz in 1..{MAX_RATE_HZ}, got "
                             f"{self.rate_hz:g}")
        for name in ("input_scale", "output_step"):
            step = np.asarray(getattr(self, name))
            if step.shape != (6,) or not np.all(np.isfinite(step)) or np.any(step <= 0):
                raise ValueError(f"{name} must be six positive numbers")
        scale = np.asarray(self.input_scale, dtype=float)
        if np.any(scale < INPUT_SCALE_RANGE[0]) or np.any(scale > INPUT_SCALE_RANGE[1]):
            raise ValueError(f"input_scale must lie in {INPUT_SCALE_RANGE[0]:g}.."
                             f"{INPUT_SCALE_RANGE[1]:g} input steps per N (N*m)")
        # Bound only what would overflow: the correction's range (INT16_MAX output steps) at
        # most MAX_OUTPUT_RANGES times the base wrench's input range (INT16_MAX / input_scale).
        if np.any(np.asarray(self.output_step, dtype=float) * scale > MAX_OUTPUT_RANGES):
            raise ValueError(f"output_step: 32767 steps of correction must stay within "
                             f"{MAX_OUTPUT_RANGES} times the input's range of the base wrench "
                             "(32767 / input_scale)")
        for f in self.features:
            if f.kind not in FEATURE_KINDS:
                raise ValueError(f"unknown feature kind {f.kind!r}")
            if f.kind in PLAIN_KINDS and f.param != 0:
                raise ValueError(f"a {f.kind} feature takes no parameter (0), not {f.param}")
            if f.kind == "play" and not 1 <= f.param <= MAX_PLAY_RADIUS:
                raise ValueError(f"play radius {f.param} outside 1..{MAX_PLAY_RADIUS} counts")
            if f.kind in STEP_KINDS and f.param not in (1, 2):
                raise ValueError(f"a step looks back 1 or 2 periods, not {f.param}")
            _check_requant(f.multiplier, f.shift, 6, FEATURE_SHIFTS, f.kind)
        width = self.inputs
        if width > MAX_WIDTH:
            raise ValueError(f"{width} inputs, more than {MAX_WIDTH}")
        for i, layer in enumerate(self.layers):
            out, inp = layer.shape
            last = i == len(self.layers) - 1
            if np.ndim(layer.bias) == 1 and len(layer.bias) != out:
                # the weights first: a missing row is not the bias's fault
                raise ValueError(f"layer {i + 1}: {out} rows of weights but {len(layer.bias)} "
                                 "biases (one row per output)")
            if inp != width:
                raise ValueError(f"layer {i + 1} takes {inp} inputs, the one before gives {width}")
            if out > MAX_WIDTH or (last and out != 6) or layer.relu == last:
                raise ValueError(f"layer {i + 1}: hidden layers are ReLU, the last gives 6 outputs")
            if layer.weights.dtype != np.int8 or np.any(layer.weights == -128):
                raise ValueError(f"layer {i + 1}: weights must be int8 in -127..127")
            if layer.bias.shape != (out,) or np.any(np.abs(layer.bias.astype(np.int64)) >= 2**30):
                raise ValueError(f"layer {i + 1}: bias must be {out} int32 below 2^30")
            _check_requant(layer.multiplier, layer.shift, out, LAYER_SHIFTS, f"layer {i + 1}")
            width = out
        return self


def _check_requant(multiplier, shift, n, shifts, what) -> None:
    m, s = np.asarray(multiplier), np.asarray(shift)
    if m.shape != (n,) or s.shape != (n,):
        raise ValueError(f"{what}: {n} multipliers and shifts expected")
    if np.any(m < MULT_MIN) or np.any(m >= MULT_LIMIT) or np.any(s < shifts[0]) or np.any(s > shifts[1]):
        raise ValueError(f"{what}: multipliers must be in [2^14, 2^15) and shifts in "
                         f"{shifts[0]}..{shifts[1]}")


def stride_for(net: Int8Net, board_rate_hz: float) -> int:
    """Board samples per model period: max(1, round(board rate / model rate)), at most
    MAX_STRIDE. Computed in integers as the board does: (2 R + r) // (2 r) with the model's
    rate r rounded to a whole number of Hz."""
    r = max(1, int(round(net.rate_hz)))
    return max(1, min(MAX_STRIDE, (2 * int(board_rate_hz) + r) // (2 * r)))


@dataclass
class State:
    """What the board carries between samples: the recent base wrench and counts (newest
    last) and the play outputs; ``None`` until the first valid sample (or after a reset)."""

    base: np.ndarray | None = None     # (k, 6) int64, the last samples
    counts: np.ndarray | None = None   # (k, 6) int64
    plays: np.ndarray | None = None    # (P, 6) int64


def quantize_input(wrench, input_scale) -> np.ndarray:
    """Base wrench (N, N*m) -> int16 input steps as the board computes it: float32 product with
    the scale, saturated, rounded half away from zero (lroundf)."""
    v = np.asarray(wrench, dtype=np.float32) * np.asarray(input_scale, dtype=np.float32)
    v = np.clip(v, np.float32(INT16_MIN), np.float32(INT16_MAX)).astype(np.float64)
    # |v| + 0.5 in float64 is exact for a float32 v of int16 range; in float32 it rounds up
    # just below a half (0.49999997 + 0.5 -> 1.0), where lroundf gives 0.
    return (np.sign(v) * np.floor(np.abs(v) + 0.5)).astype(np.int64)


def apply_output(wrench, correction, output_step) -> np.ndarray:
    """The corrected wrench as the board computes it in float32: base + correction * step."""
    return (np.asarray(wrench, dtype=np.float32)
            + np.asarray(correction).astype(np.float32) * np.asarray(output_step, dtype=np.float32))


def run(net: Int8Net, base: np.ndarray, counts: np.ndarray, *, stride: int = 1,
        valid: np.ndarray | None = None, state: State | None = None) -> tuple[np.ndarray, State]:
    """The corrections (n, 6) int64 for n samples of int16 inputs ``base`` and ``counts``
    (n, 6); rows where ``valid`` is False get 0 and reset the state. Returns the corrections
    and the state after the last sample (pass it back to continue a stream)."""
    base = np.asarray(base, dtype=np.int64).reshape(-1, 6)
    counts = np.asarray(counts, dtype=np.int64).reshape(-1, 6)
    n = len(base)
    valid = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    state = state if state is not None else State()
    out = np.zeros((n, 6), dtype=np.int64)
    # Contiguous runs of valid samples; the first run may continue the incoming state.
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(np.int8), [0]])))
    for k, (start, stop) in enumerate(zip(edges[::2], edges[1::2])):
        carry = state if (k == 0 and start == 0) else State()
        out[start:stop], state = _run_segment(net, base[start:stop], counts[start:stop], stride,
                                              carry)
    if n and not valid[-1]:
        state = State()
    return out, state


def _run_segment(net, base, counts, stride, state: State) -> tuple[np.ndarray, State]:
    v, after = _segment_features(net.features, net.history_length(), base, counts, stride, state)
    groups = []
    for g, f in enumerate(net.features):
        groups.append(saturate(requantize(v[:, 6 * g:6 * g + 6], f.multiplier, f.shift),
                               -INT8_MAX, INT8_MAX))
    x = np.concatenate(groups, axis=1)
    for layer in net.layers:
        acc = x @ layer.weights.astype(np.int64).T + layer.bias.astype(np.int64)
        y = requantize(acc, layer.multiplier, layer.shift)
        x = saturate(y, 0, INT8_MAX) if layer.relu else saturate(y, INT16_MIN, INT16_MAX)
    return x, after


def history_length(features) -> int:
    """Ring entries the board keeps per history source for ``features`` (kind, param)."""
    lag = max((f.param for f in features if f.kind in STEP_KINDS), default=0)
    return lag * MAX_STRIDE + 1 if lag else 0


def feature_values(features, base, counts, *, stride: int = 1, valid=None) -> np.ndarray:
    """The int16 feature values (n, 6 * len(features)) before their int8 requantization, for
    any objects with ``kind`` and ``param`` (training uses them before a network exists).
    Rows where ``valid`` is False are 0 and restart the history, as in :func:`run`."""
    base = np.asarray(base, dtype=np.int64).reshape(-1, 6)
    counts = np.asarray(counts, dtype=np.int64).reshape(-1, 6)
    n = len(base)
    valid = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    out = np.zeros((n, 6 * len(features)), dtype=np.int64)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(np.int8), [0]])))
    for start, stop in zip(edges[::2], edges[1::2]):
        out[start:stop], _ = _segment_features(features, history_length(features),
                                               base[start:stop], counts[start:stop], stride,
                                               State())
    return out


def _segment_features(features, history, base, counts, stride, state: State):
    keep = max(1, (history - 1) // MAX_STRIDE * stride + 1)
    radii = np.array([f.param for f in features if f.kind == "play"], dtype=np.int64)
    if state.base is None:   # primed: the past equals the first sample, plays centred on it
        past_base, past_counts = base[:1].repeat(keep, 0), counts[:1].repeat(keep, 0)
        plays = counts[:1].repeat(len(radii), 0)
    else:
        past_base, past_counts, plays = state.base, state.counts, state.plays
    hb = np.concatenate([past_base, base])[-(keep + len(base) - 1):] if keep > 1 else base
    hc = np.concatenate([past_counts, counts])[-(keep + len(counts) - 1):] if keep > 1 else counts
    rows = np.arange(len(base)) + keep - 1   # row i of the segment in the history
    play_out, plays_after = _plays(counts, radii, plays)
    columns, p = [], 0
    for f in features:
        if f.kind == "wrench":
            v = base
        elif f.kind == "counts":
            v = counts
        elif f.kind in STEP_KINDS:
            h = hb if f.kind == "wrench_step" else hc
            v = h[rows - (f.param - 1) * stride] - h[rows - f.param * stride]
        else:
            v = counts - play_out[:, p]
            p += 1
        columns.append(saturate(v, INT16_MIN, INT16_MAX))
    after = State(base=hb[-keep:].copy(), counts=hc[-keep:].copy(), plays=plays_after)
    return np.concatenate(columns, axis=1), after


def _plays(x: np.ndarray, radii: np.ndarray, y0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Play operators y_n = clamp(y_(n-1), x_n - r, x_n + r) on integer counts: (n, P, 6)
    outputs and the last (P, 6), by the blocked scan of :func:`delta6.core.operators.play`."""
    n = len(x)
    if len(radii) == 0:
        return np.zeros((n, 0, 6), dtype=np.int64), np.zeros((0, 6), dtype=np.int64)
    y = play(x[:, None, :].astype(float), radii[None, :, None].astype(float),
             np.asarray(y0, dtype=float))
    # Integer inputs and radii: every clamp is exact in float64 (|x| < 2^53).
    y = np.rint(y).astype(np.int64)
    return y, y[-1].copy()
