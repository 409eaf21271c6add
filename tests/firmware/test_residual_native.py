"""The residual engine compiled natively against the numpy integer reference: the same
integers for every sample, state included, over random networks and streams, recorded twin
trajectories, the float edges, and a model compiled from its generated header."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.build import nativeresidual
from delta6.build.nativeresidual import NativeResidual
from delta6.core import int8net, residualmodel
from delta6.core.model import ENCODER_COUNT_RAD
from delta6_codegen import render_model

from support.int8nets import random_features, random_int8net, random_stream, trained_like

BOARD_RATES = (1, 10, 50, 100, 250, 300, 350, 400, 1000)


@pytest.fixture(scope="module")
def lib():
    return nativeresidual.library()


@given(st.integers(-2**15, 2**15 - 1), st.integers(-2**15, 2**15 - 1), st.integers(1, 30))
def test_requantize16_matches(value, m, s):
    lib = nativeresidual.library()
    assert lib.d6r_requantize16(value, m, s) == int(int8net.requantize(value, m, s))


@given(st.integers(-2**31, 2**31 - 1), st.integers(-2**15, 2**15 - 1), st.integers(16, 46))
def test_requantize32_matches(acc, m, s):
    lib = nativeresidual.library()
    assert lib.d6r_requantize32(acc, m, s) == int(int8net.requantize(acc, m, s))


@pytest.mark.parametrize("acc", [-2**31, 2**31 - 1, -1, 0, 1, -2**16, 2**16 - 1])
@pytest.mark.parametrize("m", [-2**15, 2**15 - 1, 2**14, -1])
@pytest.mark.parametrize("s", [16, 17, 31, 46])
def test_requantize32_extremes(lib, acc, m, s):
    assert lib.d6r_requantize32(acc, m, s) == int(int8net.requantize(acc, m, s))


def _compare(lib, net, base, counts, valid, board_rate, pieces=3, seed=0):
    stride = int8net.stride_for(net, board_rate)
    ref, _ = int8net.run(net, base, counts, stride=stride, valid=valid)
    rng = np.random.default_rng(seed)
    cuts = np.sort(rng.choice(np.arange(1, len(base)), pieces - 1, replace=False))
    with NativeResidual(net, board_rate, lib=lib) as c:
        assert c.stride == stride
        got = np.concatenate([c.feed(base[a:b], counts[a:b], valid[a:b])
                              for a, b in zip([0, *cuts], [*cuts, len(base)])])
    mismatch = np.flatnonzero(np.any(got != ref, axis=1))
    assert not len(mismatch), f"first mismatch at sample {mismatch[0]}: {got[mismatch[0]]} " \
                              f"!= {ref[mismatch[0]]}"
    return ref


def test_random_networks_and_streams(lib):
    """Over 40 random networks x 400 samples (16,000 samples): any weights, biases,
    multipliers and shifts, invalid samples, every kind of feature, board rates from 1 Hz."""
    rng = np.random.default_rng(2024)
    for trial in range(40):
        net = random_int8net(rng)
        base, counts, valid = random_stream(rng, 400, gaps=0.02)
        _compare(lib, net, base, counts, valid, BOARD_RATES[trial % len(BOARD_RATES)],
                 seed=trial)


def test_trained_like_networks_on_recorded_trajectories(lib, baseline):
    """Networks quantized like trained ones (realistic scales, few saturations), on a
    recorded twin trajectory of the paper scenario: 2 x 6,000 samples with the analytical
    wrench as the base."""
    from delta6 import twin
    from delta6.core import model
    run = twin.simulate(baseline, twin.scenario_effects("paper", 3), 120.0, seed=3)
    scale = np.float32(16384.0 / np.array([20, 20, 40, 1, 1, 0.5]))
    base = int8net.quantize_input(model.wrench(baseline, run.theta), scale)
    counts = np.round(run.theta / ENCODER_COUNT_RAD).astype(np.int64)
    valid = np.ones(len(base), dtype=bool)
    valid[[700, 701, 3000]] = False
    rng = np.random.default_rng(7)
    for board_rate in (50, 250):
        features = random_features(rng, 5)
        v = int8net.feature_values(features, base, counts)
        _, net = trained_like(rng, features, v, hidden=(24, 12))
        ref = _compare(lib, net, base, counts, valid, board_rate, pieces=5)
        assert np.count_nonzero(ref) > 0.5 * ref.size   # the outputs are not all saturated or 0


@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False, width=32), min_size=6, max_size=6),
       st.lists(st.integers(-32768, 32767), min_size=6, max_size=6))
def test_float_edges_match_float32(wrench, correction):
    net = random_int8net(np.random.default_rng(1))
    with NativeResidual(net) as c:
        np.testing.assert_array_equal(c.quantize_input([wrench])[0],
                                      int8net.quantize_input(wrench, net.input_scale))
        np.testing.assert_array_equal(
            c.apply_output([correction], [wrench])[0],
            int8net.apply_output(wrench, correction, net.output_step))


def test_input_rounding_just_below_and_at_the_halves_is_lroundf():
    """Half away from zero, as lroundf: 0.49999997 rounds to 0 (|v| + 0.5 in float32 gives
    1.0), 0.5 to 1, -2.5 to -3."""
    import dataclasses
    net = dataclasses.replace(random_int8net(np.random.default_rng(1)),
                              input_scale=np.ones(6, dtype=np.float32))
    below = float(np.nextafter(np.float32(0.5), np.float32(0)))
    values = [[below, 0.5, -below, -0.5, 2.5, -2.5],
              [1.5 - 2**-23, 1.5, 32766.5, -32767.5, 1e9, -1e9]]
    expected = [[0, 1, 0, -1, 3, -3], [1, 2, 32767, -32768, 32767, -32768]]
    with NativeResidual(net) as c:
        np.testing.assert_array_equal(c.quantize_input(values), expected)
    np.testing.assert_array_equal(int8net.quantize_input(values, net.input_scale), expected)


def test_generated_header_compiles_to_the_same_model(tmp_path):
    rng = np.random.default_rng(11)
    net = random_int8net(rng)
    model = residualmodel.ResidualModel(name="gen-test", design_name="delta6",
                                        design_hash=0x535534AF, base="analytical", net=net)
    (tmp_path / "generated").mkdir()
    (tmp_path / "generated" / "delta6_model.h").write_text(
        render_model(model, "designs/delta6.toml", "gen.json"))
    lib = nativeresidual.library(tmp_path)
    assert lib.d6r_generated_hash() == model.hash32()
    base, counts, valid = random_stream(rng, 1500, gaps=0.01)
    stride = int8net.stride_for(net, 250)
    ref, _ = int8net.run(net, base, counts, stride=stride, valid=valid)
    with NativeResidual(net, 250, lib=lib, generated=True) as c:
        np.testing.assert_array_equal(c.feed(base, counts, valid), ref)
