"""The float residual network and its post-training quantization into an :class:`Int8Net`.

The float network sees the same integer feature values v as the integer one
(:func:`delta6.core.int8net.feature_values`): z = v * input_gain, hidden layers
h = relu(W h + b), and the correction in N (N*m) = (W h + b) * output_gain.

Quantization (per output channel, symmetric, zero point 0):

* each input element gets a scale s_x from its range on calibration data (the 99.99th
  percentile of |z|), so x_q = round(v * gain / s_x): the feature requantizer (m, s) is the
  nearest representable gain / s_x, and the scale actually used is gain / (m 2^-s);
* each layer's input scales are folded into its weight columns, each row is quantized with its
  own scale s_w = max |row| / 127, the bias with the same scale (int32);
* a hidden neuron's output scale s_h comes from its range on the calibration data; the
  requantizer is s_w / s_h (kept below 1/2, the engine's shift range); the next layer folds the
  s_h actually represented into its columns;
* the output layer's requantizer is s_w * output_gain / output_step, with output steps fine
  enough to be negligible (1/4 of the largest correction over 32767, at least) and coarse
  enough for the shift range.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from delta6.core import int8net
from delta6.core.int8net import FEATURE_SHIFTS, LAYER_SHIFTS, Feature, Int8Net, Layer

#: Ranges are taken at this percentile of |value| on the calibration data (not the maximum:
#: one outlier would waste the int8 range of every other sample).
RANGE_PERCENTILE = 99.99
#: Largest requantization multiplier of a dense layer (the shift range starts at 16).
MAX_LAYER_MULTIPLIER = 0.499
#: The correction's int16 range covers this many times its largest value on the data.
OUTPUT_HEADROOM = 4.0


@dataclass(frozen=True)
class FeatureSpec:
    kind: str
    param: int = 0


@dataclass(frozen=True)
class FloatNet:
    rate_hz: float
    input_scale: np.ndarray          # (6,) float32, as in Int8Net
    features: tuple[FeatureSpec, ...]
    input_gain: np.ndarray           # (n_in,)
    weights: tuple[np.ndarray, ...]  # (out, in) per layer
    biases: tuple[np.ndarray, ...]
    output_gain: np.ndarray          # (6,) N (N*m) per output unit

    def forward(self, v: np.ndarray, *, hidden: bool = False):
        """Corrections (n, 6) in N, N*m for feature values ``v`` (n, n_in); with ``hidden``
        also the hidden activations of each layer."""
        h = np.asarray(v, dtype=float) * self.input_gain
        acts = []
        for i, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = h @ np.asarray(w, float).T + b
            if i < len(self.weights) - 1:
                h = np.maximum(h, 0.0)
                acts.append(h)
        y = h * self.output_gain
        return (y, acts) if hidden else y


def _range(values: np.ndarray) -> np.ndarray:
    return np.percentile(np.abs(values), RANGE_PERCENTILE, axis=0) if len(values) else \
        np.zeros(values.shape[1:])


def _requantizer(real: np.ndarray, shifts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per element (m, s) nearest ``real`` clipped into what ``shifts`` represent, and the
    value m / 2^s actually represented."""
    lo = int8net.MULT_MIN * 2.0 ** -shifts[1]
    hi = (int8net.MULT_LIMIT - 1) * 2.0 ** -shifts[0]
    ms = [int8net.quantize_multiplier(float(np.clip(r, lo, hi)), shifts) for r in real]
    m = np.array([a for a, _ in ms], dtype=np.int16)
    s = np.array([b for _, b in ms], dtype=np.uint8)
    return m, s, m.astype(float) * 2.0 ** -s.astype(float)


def _quantize_rows(w: np.ndarray, b: np.ndarray):
    """Per-row symmetric int8 weights, int32 bias in the same scale; returns (wq, bq, s_w)."""
    s_w = np.max(np.abs(w), axis=1) / int8net.INT8_MAX
    s_w = np.where(s_w > 0, s_w, 1.0)
    s_w = np.maximum(s_w, np.abs(b) / 2.0**29)       # the bias stays below 2^29 in that scale
    wq = np.clip(np.round(w / s_w[:, None]), -127, 127).astype(np.int8)
    bq = np.round(b / s_w).astype(np.int64)
    return wq, bq.astype(np.int32), s_w


def quantize(net: FloatNet, calibration: np.ndarray, output_step: np.ndarray | None = None
             ) -> Int8Net:
    """The integer network for ``net``, its ranges taken from feature values ``calibration``
    (n, n_in), typically the training set."""
    v = np.asarray(calibration, dtype=float)
    z = v * net.input_gain
    s_x = np.maximum(_range(z), 1e-12) / int8net.INT8_MAX
    fm, fs, represented = _requantizer(net.input_gain / s_x, FEATURE_SHIFTS)
    scale_in = net.input_gain / represented                # the s_x actually used
    features = tuple(
        Feature(f.kind, int(f.param), tuple(int(x) for x in fm[6 * g:6 * g + 6]),
                tuple(int(x) for x in fs[6 * g:6 * g + 6]))
        for g, f in enumerate(net.features))
    _, acts = net.forward(v, hidden=True)
    y = net.forward(v)
    layers = []
    last = len(net.weights) - 1
    for i, (w, b) in enumerate(zip(net.weights, net.biases)):
        w_folded = np.asarray(w, float) * scale_in[None, :]
        wq, bq, s_w = _quantize_rows(w_folded, np.asarray(b, float))
        if i < last:
            s_h = np.maximum(_range(acts[i]) / int8net.INT8_MAX, s_w / MAX_LAYER_MULTIPLIER)
            m, s, rep = _requantizer(s_w / s_h, LAYER_SHIFTS)
            scale_in = s_w / rep
            layers.append(Layer(wq, bq, m, s, True))
        else:
            if output_step is None:
                largest = np.maximum(_range(y), 1e-9)
                step = np.maximum(OUTPUT_HEADROOM * largest / int8net.INT16_MAX,
                                  s_w * net.output_gain / MAX_LAYER_MULTIPLIER)
                output_step = step.astype(np.float32)
            m, s, _ = _requantizer(s_w * net.output_gain / np.asarray(output_step, float),
                                   LAYER_SHIFTS)
            layers.append(Layer(wq, bq, m, s, False))
    return Int8Net(float(net.rate_hz), np.asarray(net.input_scale, np.float32),
                   np.asarray(output_step, np.float32), features, tuple(layers)).check()
