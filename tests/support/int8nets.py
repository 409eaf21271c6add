"""Networks and input streams for the residual engine's cross-checks."""
from __future__ import annotations

import numpy as np

from delta6.core import int8net, int8quant
from delta6.core.int8net import Feature, Int8Net, Layer
from delta6.core.int8quant import FeatureSpec, FloatNet

KINDS = tuple(int8net.FEATURE_KINDS)


def random_features(rng, groups: int | None = None) -> list[FeatureSpec]:
    out = []
    for _ in range(groups or int(rng.integers(1, 7))):
        kind = str(rng.choice(KINDS))
        param = (int(rng.integers(1, 3)) if kind in int8net.STEP_KINDS
                 else int(rng.integers(1, 400)) if kind == "play" else 0)
        out.append(FeatureSpec(kind, param))
    return out


def random_int8net(rng, *, rate_hz: float = 50.0) -> Int8Net:
    """Any network the engine accepts: random multipliers, shifts, weights and biases over
    their whole ranges (so saturation and every shift are exercised)."""
    feats = [Feature(f.kind, f.param,
                     tuple(int(v) for v in rng.integers(int8net.MULT_MIN, int8net.MULT_LIMIT, 6)),
                     tuple(int(v) for v in rng.integers(1, 31, 6)))
             for f in random_features(rng)]
    width, layers = 6 * len(feats), []
    count = int(rng.integers(1, 4))
    for i in range(count):
        last = i == count - 1
        out = 6 if last else int(rng.integers(1, 33))
        layers.append(Layer(rng.integers(-127, 128, (out, width)).astype(np.int8),
                            rng.integers(-2**29, 2**29, out).astype(np.int32),
                            rng.integers(int8net.MULT_MIN, int8net.MULT_LIMIT, out).astype(np.int16),
                            rng.integers(16, 47, out).astype(np.uint8), not last))
        width = out
    return Int8Net(rate_hz, np.float32(rng.uniform(0.5, 50.0, 6)),
                   np.float32(rng.uniform(1e-5, 1e-2, 6)), tuple(feats), tuple(layers)).check()


def random_stream(rng, n: int, *, gaps: float = 0.01):
    """Random walks of the base wrench (input steps) and the counts, with invalid samples."""
    base = np.clip(np.cumsum(rng.integers(-400, 401, (n, 6)), axis=0), -32768, 32767)
    counts = np.clip(np.cumsum(rng.integers(-6, 7, (n, 6)), axis=0), -1400, 1400)
    valid = rng.random(n) >= gaps
    return base, counts, valid


def trained_like(rng, features, v: np.ndarray, hidden=(16,), rate_hz: float = 50.0) -> Int8Net:
    """A float network with random weights over feature values ``v``, quantized as training
    would: realistic scales and multipliers instead of random ones."""
    gain = 1.0 / np.maximum(v.std(axis=0), 1.0)
    sizes = [v.shape[1], *hidden, 6]
    weights = tuple(rng.normal(0, 1 / np.sqrt(a), (b, a)) for a, b in zip(sizes, sizes[1:]))
    biases = tuple(rng.normal(0, 0.1, b) for b in sizes[1:])
    net = FloatNet(rate_hz, np.full(6, 100.0, np.float32), tuple(features), gain, weights,
                   biases, np.full(6, 0.01))
    return net, int8quant.quantize(net, v)
