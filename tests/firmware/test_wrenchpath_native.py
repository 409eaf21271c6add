"""The firmware's low-pass filter and tool transform, compiled natively, against the Python
references (bit for bit) and against independent oracles: scipy's Butterworth design and
lfilter in float64, and the rigid-body wrench transform written with plain vectors."""
from __future__ import annotations

import ctypes

import numpy as np
import pytest
import scipy.signal
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.build.nativebuild import FIRMWARE_CORE, FIRMWARE_NATIVE, load_library
from delta6.core import lowpass, toolframe

F32P = ctypes.POINTER(ctypes.c_float)


@pytest.fixture(scope="module")
def lib():
    lib = load_library("wrenchpath", [FIRMWARE_NATIVE / "wrenchpath_shim.cpp",
                                      FIRMWARE_CORE / "delta6_filter.cpp",
                                      FIRMWARE_CORE / "delta6_toolframe.cpp"], [FIRMWARE_CORE])
    lib.d6_design_lowpass.argtypes = [ctypes.c_float, ctypes.c_float, F32P, F32P]
    lib.d6_run_lowpass.argtypes = [ctypes.c_float, ctypes.c_float, ctypes.c_size_t, F32P]
    lib.d6_tool_frame.argtypes = [F32P, F32P, ctypes.c_size_t, F32P]
    return lib


def design(lib, cutoff, rate):
    c, a2 = ctypes.c_float(), ctypes.c_float()
    ok = lib.d6_design_lowpass(cutoff, rate, ctypes.byref(c), ctypes.byref(a2))
    return (c.value, a2.value) if ok else None


def run(lib, c, a2, x):
    w = np.ascontiguousarray(x, dtype=np.float32).copy()
    lib.d6_run_lowpass(c, a2, len(w), w.ctypes.data_as(F32P))
    return w


rates = st.sampled_from([50, 100, 250, 350, 500, 1000, 1800])


@given(rates, st.floats(0.0005, 0.45))
def test_the_design_is_scipys_butterworth(lib, rate, ratio):
    cutoff = float(np.float32(ratio * rate))
    if not lowpass.in_range(cutoff, rate):
        assert design(lib, cutoff, rate) is None
        return
    c, a2 = design(lib, cutoff, rate)
    b, a = scipy.signal.butter(2, cutoff, fs=rate)
    assert np.allclose(lowpass.transfer(c, a2)[0], b, rtol=2e-5)
    assert np.allclose(lowpass.transfer(c, a2)[1], a, rtol=2e-5, atol=2e-6)
    assert np.allclose((c, a2), lowpass.design(cutoff, rate), rtol=2e-5)


def test_cutoffs_outside_the_range_are_refused(lib):
    assert design(lib, 0.2, 250) is None              # below 0.001 x rate
    assert design(lib, 113, 250) is None              # above 0.45 x rate
    assert design(lib, float("nan"), 250) is None and design(lib, 10, 0) is None
    assert design(lib, 0.25, 250) is not None and design(lib, 112.5, 250) is not None


@given(rates, st.floats(0.0005, 0.45), st.integers(0, 2**32 - 1))
def test_float32_filter_is_the_python_reference_bit_for_bit(lib, rate, ratio, seed):
    coeffs = design(lib, float(np.float32(ratio * rate)), rate)
    if coeffs is None:
        return
    rng = np.random.default_rng(seed)
    x = (rng.normal(size=(300, 6)) * rng.uniform(0.01, 30, 6)).astype(np.float32)
    assert np.array_equal(run(lib, *coeffs, x), lowpass.run(x, *coeffs))


@pytest.mark.parametrize("rate, cutoff", [(250, 0.25), (250, 2.5), (250, 30), (250, 112.5),
                                          (1000, 1), (1000, 100), (400, 0.4)])
def test_float32_filter_follows_scipys_float64_lfilter(lib, rate, cutoff):
    """Within 2e-6 of full scale (a thirtieth of the smallest LSB in use, 2e-5 N*m on 0.4 N*m
    axes) over 20 s of a wrench at full scale, from a steady start, across the range."""
    c, a2 = design(lib, cutoff, rate)
    b, a = lowpass.transfer(c, a2)
    n = 20 * rate
    t = np.arange(n) / rate
    rng = np.random.default_rng(1)
    full = np.array([15.0, 15.0, 25.0, 0.38, 0.33, 0.43])
    x = full * (0.5 * np.sin(2 * np.pi * rng.uniform(0.05, 3, 6) * t[:, None] + rng.uniform(0, 6, 6))
                + 0.3 * rng.uniform(-1, 1, (n, 6)) + 0.2)
    x = x.astype(np.float32).astype(float)
    zi = scipy.signal.lfilter_zi(b, a)[:, None] * x[0]
    want, _ = scipy.signal.lfilter(b, a, x, axis=0, zi=zi)
    got = run(lib, c, a2, x)
    err = np.abs(got - want).max(axis=0) / full
    assert err.max() < 2e-6, err


def test_gain_at_dc_is_exactly_one_and_flagged_samples_can_be_skipped(lib):
    c, a2 = design(lib, 2.5, 250)
    x = np.full((2000, 6), [1.5, -2.25, 24.0, 0.125, -0.3, 0.0], dtype=np.float32)
    assert np.array_equal(run(lib, c, a2, x), x)               # no start transient, no drift
    step = x.copy()
    step[100:] += 1.0
    y = run(lib, c, a2, step)
    assert np.allclose(y[-1], step[-1], atol=1e-6)              # settles on the new level
    assert (y[101:, 0] <= step[-1, 0] + 0.05).all()             # Butterworth: ~4 % overshoot


tool = st.tuples(arrays(np.float32, 3, elements=st.floats(-0.25, 0.25, width=32)),
                 arrays(np.float32, 3, elements=st.floats(-3.125, 3.125, width=32)))


@given(tool, arrays(np.float32, (8, 6), elements=st.floats(-30, 30, width=32)))
def test_tool_transform_matches_the_rigid_body_reference(lib, frame, w):
    p, rpy = frame
    got = w.copy()
    assert lib.d6_tool_frame(p.ctypes.data_as(F32P), rpy.ctypes.data_as(F32P), len(got),
                             got.ctypes.data_as(F32P)) == 1
    want = toolframe.to_tool(w.astype(float), p.astype(float), rpy.astype(float))
    scale = 1 + np.abs(w).max()
    assert np.allclose(got, want, atol=2e-6 * scale)
    # Independent of the reference: the moment about the tool point, by the definition
    # M_p = sum of r x f moved, and the force's length kept by a rotation.
    r = toolframe.rotation(rpy.astype(float))
    f = w[:, :3].astype(float)
    assert np.allclose(np.linalg.norm(got[:, :3], axis=1), np.linalg.norm(f, axis=1), atol=1e-5 * scale)
    assert np.allclose(got[:, 3:] @ r.T, w[:, 3:] + np.cross(f, p.astype(float)), atol=1e-5 * scale)


def test_identity_frame_leaves_the_wrench_untouched_and_nan_frames_are_refused(lib):
    w = np.arange(12, dtype=np.float32).reshape(2, 6) / 7
    zero = np.zeros(3, np.float32)
    got = w.copy()
    assert lib.d6_tool_frame(zero.ctypes.data_as(F32P), zero.ctypes.data_as(F32P), 2,
                             got.ctypes.data_as(F32P)) == 1
    assert np.array_equal(got, w)
    bad = np.array([0, np.nan, 0], np.float32)
    assert lib.d6_tool_frame(bad.ctypes.data_as(F32P), zero.ctypes.data_as(F32P), 2,
                             got.ctypes.data_as(F32P)) == 0
