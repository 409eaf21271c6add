"""The device's wrench pipeline (low-pass -> tool frame -> tare -> quantise -> limits) as the
firmware core runs it, natively, against the Python references (delta6.core.lowpass,
delta6.core.toolframe, delta6.link.wirescale.quantize); the OVERRANGE flag exactly at the
threshold; the configuration in EEPROM, including a blob of the previous layout."""
from __future__ import annotations

import ctypes

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6.build.nativebuild import FIRMWARE_CORE, FIRMWARE_NATIVE, load_library
from delta6.core import lowpass, toolframe
from delta6.link import protocol as P
from delta6.link import wirescale
from delta6.link.crc import crc16
from delta6.link.decoder import StreamDecoder
from delta6.sim.simdevice import NativeCore

C = P.Command
FULL_SCALE = np.array([15.03, 15.03, 25.10, 0.3805, 0.3347, 0.4266])
HASH = 0x535534AF
RATE = 500


class Core:
    """The firmware's Device behind the simulated board, fed with wrenches chosen here."""

    def __init__(self, eeprom: bytes | None = None, design_hash: int = HASH,
                 max_rate_hz: int = 2000, max_rate_pipeline_hz: int = 0):
        self.core = NativeCore(design_name="pipeline", design_hash=design_hash,
                               full_scale=FULL_SCALE, joint_limit_rad=0.5,
                               joint_limit_counts=0, baud=2_000_000, max_rate_hz=max_rate_hz,
                               default_rate_hz=min(RATE, max_rate_hz), zero_counts=[0] * 6,
                               tx_capacity=60000)
        self.core.set_max_rate_pipeline(max_rate_pipeline_hz)
        if eeprom is not None:
            self.core.eeprom = eeprom
        self.decoder = StreamDecoder()
        self.t_us = 0
        self.request = 0
        self.other = []        # what samples() received besides data records (late answers)
        self.core.begin(0)
        self.boot = self.decoder.feed(self.core.read())

    def close(self):
        self.core.close()

    def command(self, command, *args):
        self.request = self.request % 255 + 1
        self.core.set_time(self.t_us)
        self.core.feed(P.encode_command(command, self.request, *args))
        records = self.decoder.feed(self.core.read())
        answer = [r for r in records if not isinstance(r, P.WrenchRecord)
                  and getattr(r, "request_id", 0) == self.request]
        assert len(answer) == 1, records
        return answer[0]

    def info(self) -> P.Info:
        return self.command(C.GET_INFO)

    def samples(self, wrench, invalid=None) -> list:
        """One sample per row of ``wrench`` (float32, N and N*m); ``invalid`` rows carry a
        failed encoder read (no wrench). Returns the data records sent."""
        wrench = np.asarray(wrench, dtype=np.float32).reshape(-1, 6)
        n = len(wrench)
        invalid = np.zeros(n, bool) if invalid is None else np.asarray(invalid, bool)
        period = 1_000_000 // RATE
        times = self.t_us + period * np.arange(1, n + 1)
        self.t_us = int(times[-1])
        self.core.samples(times, np.zeros((n, 6), np.uint16), invalid.astype(np.uint8),
                          ~invalid, wrench, np.zeros(n, np.uint8), np.full(n, 100, np.uint16))
        records = self.decoder.feed(self.core.read())
        self.other += [r for r in records if not isinstance(r, P.WrenchRecord)]
        return [r for r in records if isinstance(r, P.WrenchRecord)]


@pytest.fixture
def core():
    c = Core()
    yield c
    c.close()


@pytest.fixture(scope="module")
def coefficients():
    """The device's own filter design (float32 tanf), for bit-exact references."""
    lib = load_library("wrenchpath", [FIRMWARE_NATIVE / "wrenchpath_shim.cpp",
                                      FIRMWARE_CORE / "delta6_filter.cpp",
                                      FIRMWARE_CORE / "delta6_toolframe.cpp"], [FIRMWARE_CORE])
    f = ctypes.POINTER(ctypes.c_float)
    lib.d6_design_lowpass.argtypes = [ctypes.c_float, ctypes.c_float, f, f]

    def design(cutoff):
        c, a2 = ctypes.c_float(), ctypes.c_float()
        assert lib.d6_design_lowpass(cutoff, RATE, ctypes.byref(c), ctypes.byref(a2))
        return c.value, a2.value
    return design


def lsb32(info: P.Info) -> np.ndarray:
    return np.array([wirescale.float32_lsb(m, e) for m, e in
                     zip(info.lsb_mantissa, info.lsb_exponent)], dtype=np.float32)


def counts(records) -> np.ndarray:
    return np.array([r.wrench for r in records], dtype=np.int64)


def status(records) -> np.ndarray:
    return np.array([r.status for r in records], dtype=np.int64)


wrenches = st.integers(40, 160).flatmap(lambda n: st.tuples(
    arrays(np.float32, (n, 6), elements=st.floats(-1.25, 1.25, width=32)),
    arrays(np.bool_, n, elements=st.sampled_from([False] * 9 + [True]))))


@settings(max_examples=25, deadline=None)
@given(wrenches, st.sampled_from([0.0, 0.5, 2.5, 20.0, 100.0, 225.0]))
def test_filtered_stream_is_the_python_reference_bit_for_bit(coefficients, data, cutoff):
    """Identity tool frame, no tare: the counts sent are lowpass.run over the valid samples
    (a sample without a wrench leaves the filter alone), quantised as wirescale does."""
    w, invalid = data
    w = w * FULL_SCALE.astype(np.float32)
    invalid[0] = False
    c = Core()
    try:
        assert c.command(C.SET_FILTER, cutoff) == P.Ack(c.request, C.SET_FILTER, 0)
        info = c.info()
        assert info.filter_hz == np.float32(cutoff)
        c.command(C.START, 0)
        records = c.samples(w, invalid)
    finally:
        c.close()
    assert len(records) == len(w)
    got = counts(records)
    st_ = status(records)
    assert ((st_ & P.Status.WRENCH_INVALID) != 0).tolist() == invalid.tolist()
    assert (got[invalid] == P.INVALID_VALUE).all()
    valid = w[~invalid]
    filtered = lowpass.run(valid, *coefficients(cutoff)) if cutoff else valid
    want, _ = wirescale.quantize(filtered, lsb32(info))
    assert np.array_equal(got[~invalid], want)


tools = st.tuples(arrays(np.float32, 3, elements=st.floats(-0.015625, 0.015625, width=32)),
                  arrays(np.float32, 3, elements=st.floats(-3.125, 3.125, width=32)))


@settings(max_examples=25, deadline=None)
@given(arrays(np.float32, (60, 6), elements=st.floats(-0.5, 0.5, width=32)), tools,
       st.sampled_from([0.0, 5.0, 50.0]), st.integers(1, 20),
       arrays(np.int64, 6, elements=st.integers(0, 20000)))
def test_pipeline_matches_the_references_and_flags_overload_by_its_counts(
        coefficients, w, tool, cutoff, tare_samples, limits):
    """Filter, tool frame, tare (averaged on the device, in the tool frame) and limits
    against lowpass.run and toolframe.to_tool (float64): every count within rounding of the
    reference, OVERLOAD exactly where a sent count exceeds its limit."""
    w = w * FULL_SCALE.astype(np.float32)
    translation, rpy = tool
    c = Core()
    try:
        c.command(C.SET_FILTER, cutoff)
        assert c.command(C.SET_TOOL, *translation, *rpy) == P.Ack(c.request, C.SET_TOOL, 0)
        assert c.command(C.SET_LIMITS, *limits) == P.Ack(c.request, C.SET_LIMITS, 0)
        c.command(C.START, 0)
        records = c.samples(w[:tare_samples])
        c.core.feed(P.encode_command(C.TARE, 200, tare_samples))   # the next samples
        records += c.samples(w[tare_samples:2 * tare_samples])
        records += c.samples(w[2 * tare_samples:])
        info = c.info()
    finally:
        c.close()
    records = records[tare_samples:]
    assert info.status & P.Status.TARE_ACTIVE
    assert np.allclose(info.tool_translation, translation) and np.allclose(info.tool_rpy, rpy)
    assert info.limits == tuple(int(v) for v in limits)
    filtered = lowpass.run(w, *coefficients(cutoff)) if cutoff else w
    in_tool = toolframe.to_tool(filtered.astype(float), translation.astype(float),
                                rpy.astype(float))
    tare = in_tool[tare_samples:2 * tare_samples].mean(axis=0)
    assert np.allclose(info.tare, tare, atol=1e-5 * (1 + np.abs(in_tool).max()))
    lsb = np.asarray(info.lsb)
    after = in_tool[2 * tare_samples:] - np.asarray(info.tare)
    got = counts(records[tare_samples:])
    want = after / lsb
    slack = 0.5 + 1e-5 * (1 + np.abs(in_tool).max(axis=0) / lsb)
    assert (np.abs(got - want) <= slack).all()
    # OVERRANGE: over a limit, or clipped at the wire's range (|value| > 32767 counts; rows
    # within rounding of that edge could go either way and are not judged).
    over_limit = ((np.abs(got) > limits) & (limits > 0)).any(axis=1)
    clipped = (np.abs(want) > P.MAX_VALUE + slack).any(axis=1)
    edge = (np.abs(np.abs(want) - P.MAX_VALUE) <= slack).any(axis=1)
    flagged = (status(records[tare_samples:]) & P.Status.OVERRANGE) != 0
    assert flagged[~edge].tolist() == (over_limit | clipped)[~edge].tolist()
    assert flagged[over_limit].all()


@pytest.mark.parametrize("new_zero", ["SET_ZERO", "ZERO_HERE"])
def test_new_zero_counts_restart_the_filter_at_the_new_level(new_zero):
    """Loaded for long at 1 N with a slow filter, then new zero counts that make the solver's
    wrench 0: the first record is 0, as if the filter had always seen it (no step response
    from the old level), whichever command set the zero."""
    c = Core()
    try:
        c.command(C.SET_FILTER, 5.0)
        c.command(C.START, 0)
        c.samples(np.ones((300, 6)))
        if new_zero == "SET_ZERO":
            c.command(C.SET_ZERO, *[0] * 6)
        else:
            c.core.feed(P.encode_command(C.ZERO_HERE, 77, 10))    # averages the next 10
            c.samples(np.ones((10, 6)))
            assert P.Ack(77, C.ZERO_HERE, 10) in c.other
        after = counts(c.samples(np.zeros((5, 6))))
    finally:
        c.close()
    assert (after == 0).all(), after


@pytest.mark.parametrize("cutoff, translation, rpy, glitch", [
    (20.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (3e38, 0, 0, 0, 0, 0)),      # overflows the filter
    (20.0, (0.0, 0.0, 0.05), (0.0, 0.0, 1.5), (3e38, 0, 0, 0, 0, 0)),
    (0.0, (0.0, 0.0, 1.0), (0.3, 0.0, 0.0), (3e38, 0, 0, 0, -3e38, 0))])  # the tool frame
def test_a_huge_finite_wrench_is_flagged_and_does_not_poison_the_pipeline(cutoff, translation,
                                                                           rpy, glitch):
    """One solver value near float32's largest (an encoder glitch through a singular pose):
    whatever overflows on its way through the filter or the tool frame is sent flagged
    (SOLVER_ERROR, WRENCH_INVALID, no values), never as a value, and the filter starts again:
    the stream is back at the load's level a few samples later."""
    c = Core()
    try:
        c.command(C.SET_FILTER, cutoff)
        c.command(C.SET_TOOL, *translation, *rpy)
        c.command(C.START, 0)
        load = np.full((1, 6), 0.01)
        before = counts(c.samples(np.repeat(load, 50, axis=0)))
        records = c.samples(np.array([glitch], np.float32))
        records += c.samples(np.repeat(load, 100, axis=0))
        solver_errors = c.command(C.GET_TELEMETRY).solver_errors
    finally:
        c.close()
    got, flags = counts(records), status(records)
    invalid = (flags & P.Status.WRENCH_INVALID) != 0
    assert invalid.any() and solver_errors == invalid.sum()
    assert (flags[invalid] & P.Status.SOLVER_ERROR).all()
    assert (got[invalid] == P.INVALID_VALUE).all()
    assert (got[~invalid] != P.INVALID_VALUE).all()          # no unflagged NaN
    assert np.flatnonzero(invalid).max() < 5
    assert (got[5:] == before[-1]).all() and not (flags[5:] & P.Status.OVERRANGE).any()


def test_overload_is_exact_at_the_threshold(core):
    """A steady wrench of known counts: a limit equal to the count does not flag OVERRANGE,
    one count less does, on either sign and on each axis alone; 0 means no limit. A value
    exactly at the wire's range (-32767) is not clipped; one beyond it flags whatever the
    limits."""
    info = core.info()
    lsb = lsb32(info)
    level = np.array([1234, -2000, 3, -4, 5000, -32767])
    w = (level * lsb.astype(float)).astype(np.float32)
    core.command(C.START, 0)
    sent = counts(core.samples(np.tile(w, (3, 1))))
    assert (sent == level).all()
    assert not (status(core.samples(w)) & P.Status.OVERRANGE).any()
    for axis in range(6):
        for limit, flagged in [(abs(level[axis]), False), (abs(level[axis]) - 1, True), (0, False)]:
            limits = [0] * 6
            limits[axis] = limit
            core.command(C.SET_LIMITS, *limits)
            got = status(core.samples(w))[0]
            assert bool(got & P.Status.OVERRANGE) == flagged, (axis, limit)
    core.command(C.SET_LIMITS, *[P.MAX_VALUE] * 6)
    beyond = w.copy()
    beyond[0] = np.float32(40000 * lsb[0])                  # clipped at the wire's range
    records = core.samples(beyond)
    assert counts(records)[0][0] == P.MAX_VALUE
    assert status(records)[0] & P.Status.OVERRANGE


def test_commands_refuse_what_the_device_cannot_do(core):
    nack = core.command(C.SET_FILTER, 300.0)
    assert (nack.reason, nack.detail) == (P.NackReason.FILTER_RANGE, RATE)
    assert core.command(C.SET_FILTER, float("nan")).reason == P.NackReason.FILTER_RANGE
    assert core.command(C.SET_FILTER, -1.0).reason == P.NackReason.FILTER_RANGE
    bad_tool = core.command(C.SET_TOOL, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0)
    assert (bad_tool.reason, bad_tool.detail) == (P.NackReason.BAD_ARGUMENT, 2)
    assert core.command(C.SET_TOOL, 0.0, 0.0, 0.0, 0.0, float("inf"), 0.0).detail == 4
    assert core.command(C.SET_LIMITS, 1, 2, 3, 40000, 5, 6).detail == 40000
    info = core.info()
    assert (info.filter_hz, info.tool_translation, info.limits) == (0.0, (0.0,) * 3, (0,) * 6)
    # A cutoff that fits 500 Hz but not 100 Hz: START at 100 Hz is refused, the rate kept.
    assert isinstance(core.command(C.SET_FILTER, 100.0), P.Ack)
    nack = core.command(C.START, 100)
    assert (nack.reason, nack.detail) == (P.NackReason.FILTER_RANGE, 100)
    assert core.info().rate_hz == RATE and not core.info().streaming
    # Filter and tool wait for a tare; the limits do not.
    core.core.feed(P.encode_command(C.TARE, 250, 50))
    assert core.command(C.SET_FILTER, 10.0).reason == P.NackReason.BUSY
    assert core.command(C.SET_TOOL, *[0.0] * 6).reason == P.NackReason.BUSY
    assert isinstance(core.command(C.SET_LIMITS, *[100] * 6), P.Ack)


def test_tare_keeps_its_meaning_when_the_tool_frame_changes(core):
    """Tare a steady load, then move the reporting frame: the tared wrench stays zero, as it
    would had the tare been taken in the new frame."""
    w = (np.array([3.0, -2.0, 12.0, 0.05, -0.02, 0.01])).astype(np.float32)
    core.command(C.START, 0)
    core.samples(np.tile(w, (5, 1)))
    core.core.feed(P.encode_command(C.TARE, 250, 20))
    core.samples(np.tile(w, (20, 1)))
    assert np.abs(counts(core.samples(w))).max() <= 1
    core.command(C.SET_TOOL, 0.01, -0.005, 0.015, 0.3, -1.0, 2.0)
    assert np.abs(counts(core.samples(np.tile(w, (3, 1))))).max() <= 1
    info = core.info()
    want = toolframe.to_tool(w.astype(float), [0.01, -0.005, 0.015], [0.3, -1.0, 2.0])
    assert np.allclose(info.tare, want, atol=2e-5)
    # A load on top shows in the tool frame.
    extra = np.array([0.0, 0.0, 5.0, 0.0, 0.0, 0.0])
    got = counts(core.samples((w + extra).astype(np.float32)))[0] * info.lsb
    moved = toolframe.to_tool(extra, [0.01, -0.005, 0.015], [0.3, -1.0, 2.0])
    assert np.allclose(got, moved, atol=2 * info.lsb.max())


# --- the configuration in EEPROM --------------------------------------------------------------

def layout1_blob(rate=250, mode=P.Mode.WRENCH_RAW, tare=(0.5, -0.25, 1.0, 0.01, 0.0, -0.02),
                 zero=(1, 2, 3, 16383, 5, 6), design_hash=HASH) -> bytes:
    """A blob as firmware of protocol 1.0 saved it (layout 1), written from the table."""
    body = P.CONFIG_LAYOUTS[1].pack(magic=P.CONFIG_MAGIC, layout=1, size=P.CONFIG_BLOB_SIZES[1],
                                    design_hash=design_hash, rate_hz=rate, mode=mode,
                                    tare_active=1, tare=tare, zero_counts=zero)
    return body + crc16(body).to_bytes(2, "big")


def test_a_previous_layout_blob_loads_with_the_pipeline_at_its_defaults():
    c = Core(eeprom=layout1_blob())
    try:
        assert not [r for r in c.boot if isinstance(r, P.Event)
                    and r.code == P.EventCode.CONFIG_DEFAULTS]
        info = c.info()
        assert not info.status & P.Status.CONFIG_DEFAULTS and info.status & P.Status.TARE_ACTIVE
        assert (info.rate_hz, info.mode, info.zero_counts) == (250, P.Mode.WRENCH_RAW,
                                                               (1, 2, 3, 16383, 5, 6))
        assert np.allclose(info.tare, (0.5, -0.25, 1.0, 0.01, 0.0, -0.02))
        assert (info.filter_hz, info.tool_rpy, info.limits) == (0.0, (0.0,) * 3, (0,) * 6)
        # Saving writes the new layout, which loads with everything set.
        c.command(C.SET_FILTER, 20.0)
        c.command(C.SET_TOOL, 0.0, 0.0, 0.05, 0.0, 0.0, 1.5)
        c.command(C.SET_LIMITS, 10, 0, 30, 0, 0, 500)
        assert c.command(C.SAVE_CONFIG).value == P.CONFIG_BLOB_SIZE
        saved = c.core.eeprom[:P.CONFIG_BLOB_SIZE]
    finally:
        c.close()
    blob = P.CONFIG_LAYOUT.unpack(saved)
    assert (blob["layout"], blob["size"]) == (P.CONFIG_LAYOUT_VERSION, P.CONFIG_BLOB_SIZE)
    reborn = Core(eeprom=saved)
    try:
        info = reborn.info()
    finally:
        reborn.close()
    assert (info.filter_hz, info.limits) == (20.0, (10, 0, 30, 0, 0, 500))
    assert np.allclose(info.tool_translation, (0, 0, 0.05)) and np.allclose(info.tool_rpy, (0, 0, 1.5))
    assert not info.status & P.Status.CONFIG_DEFAULTS


@pytest.mark.parametrize("damage, reason", [
    (lambda b: b[:20] + bytes([b[20] ^ 4]) + b[21:], P.ConfigProblem.BAD_CRC),
    (lambda b: b[:2] + b"\x07" + b[3:], P.ConfigProblem.BAD_VERSION),
    (lambda b: b[:3] + bytes([P.CONFIG_BLOB_SIZE]) + b[4:], P.ConfigProblem.BAD_VERSION),
])
def test_a_damaged_previous_layout_blob_falls_back_to_defaults(damage, reason):
    c = Core(eeprom=damage(layout1_blob()))
    try:
        assert P.Event(P.EventCode.CONFIG_DEFAULTS, reason) in c.boot
        info = c.info()
        assert info.status & P.Status.CONFIG_DEFAULTS and info.rate_hz == RATE
        assert info.zero_counts == (0,) * 6
    finally:
        c.close()


def test_out_of_range_pipeline_values_in_a_blob_are_rejected_and_another_design_drops_limits():
    def saved(**changes):
        c = Core()
        try:
            c.command(C.SET_FILTER, 100.0)
            c.command(C.SET_TOOL, 0.0, 0.0, 0.05, 0.0, 0.0, 1.5)
            c.command(C.SET_LIMITS, 10, 0, 30, 0, 0, 500)
            c.command(C.SAVE_CONFIG)
            blob = P.CONFIG_LAYOUT.unpack(c.core.eeprom)
        finally:
            c.close()
        blob.update(changes)
        body = P.CONFIG_LAYOUT.pack(**blob)
        return body + crc16(body).to_bytes(2, "big")

    for bad in [dict(rate_hz=100), dict(tool_translation=(0.0, 2.0, 0.0)),
                dict(limits=(0, 0, 0, 0, 0, 40000)), dict(filter_hz=float("nan"))]:
        c = Core(eeprom=saved(**bad))
        assert P.Event(P.EventCode.CONFIG_DEFAULTS, P.ConfigProblem.OUT_OF_RANGE) in c.boot, bad
        c.close()
    other = Core(eeprom=saved(), design_hash=0x1234)
    try:
        info = other.info()
    finally:
        other.close()
    assert info.filter_hz == 100.0 and np.allclose(info.tool_translation, (0, 0, 0.05))
    assert info.limits == (0,) * 6 and not info.status & P.Status.CONFIG_DEFAULTS


def layout2_blob(rate, filter_hz=0.0, translation=(0.0,) * 3, rpy=(0.0,) * 3) -> bytes:
    """A blob saved by a faster image (another model, or none), written from the table."""
    body = P.CONFIG_LAYOUT.pack(
        magic=P.CONFIG_MAGIC, layout=P.CONFIG_LAYOUT_VERSION, size=P.CONFIG_BLOB_SIZE,
        design_hash=HASH, rate_hz=rate, mode=P.Mode.WRENCH_RAW, tare_active=1,
        tare=(0.5, -0.25, 1.0, 0.01, 0.0, -0.02), zero_counts=(1, 2, 3, 16383, 5, 6),
        filter_hz=filter_hz, tool_translation=translation, tool_rpy=rpy,
        limits=(10, 0, 30, 0, 0, 500))
    return body + crc16(body).to_bytes(2, "big")


TOOL = ((0.0, 0.0, 0.05), (0.0, 0.0, 1.5))


@pytest.mark.parametrize("blob, rate, filter_hz, tool", [
    (layout1_blob(rate=250), 200, 0.0, False),              # saved by the plain image
    (layout2_blob(250), 200, 0.0, False),
    (layout2_blob(250, filter_hz=20.0), 150, 20.0, False),  # the pipeline's lower limit
    (layout2_blob(250, 0.0, *TOOL), 150, 0.0, True),
    (layout2_blob(350, 20.0, *TOOL), 150, 20.0, True),
    # A cutoff that fits 250 Hz but not 150 Hz goes: then the rate without the filter.
    (layout2_blob(250, filter_hz=100.0), 200, 0.0, False),
    (layout2_blob(250, 100.0, *TOOL), 150, 0.0, True),
], ids=["layout1", "plain", "filter", "tool", "pipeline", "cutoff-too-high", "cutoff-tool"])
def test_a_configuration_saved_by_a_faster_image_keeps_all_but_its_rate(blob, rate, filter_hz,
                                                                         tool):
    """Reflashed with a slower image (an on-chip model: 200 Hz, 150 Hz with the filter or a
    tool frame): the saved rate is lowered to what this image runs, the zero counts, tare,
    mode, tool frame and limits stay, and INFO says RATE_LOWERED (not CONFIG_DEFAULTS) until
    SAVE_CONFIG stores the configuration as it now is."""
    c = Core(eeprom=blob, max_rate_hz=200, max_rate_pipeline_hz=150)
    try:
        assert not [r for r in c.boot if isinstance(r, P.Event)
                    and r.code == P.EventCode.CONFIG_DEFAULTS]
        info = c.info()
        assert info.config_problem == P.ConfigProblem.RATE_LOWERED
        assert not info.status & P.Status.CONFIG_DEFAULTS and info.status & P.Status.TARE_ACTIVE
        assert (info.rate_hz, info.filter_hz) == (rate, filter_hz)
        assert (info.mode, info.zero_counts) == (P.Mode.WRENCH_RAW, (1, 2, 3, 16383, 5, 6))
        assert np.allclose(info.tare, (0.5, -0.25, 1.0, 0.01, 0.0, -0.02))
        assert np.allclose(info.tool_rpy, TOOL[1] if tool else (0.0,) * 3)
        assert c.command(C.START, 0).value == rate                 # and it streams at it
        c.command(C.STOP)
        assert c.command(C.SAVE_CONFIG).value == P.CONFIG_BLOB_SIZE
        assert c.info().config_problem == 0
        saved = c.core.eeprom[:P.CONFIG_BLOB_SIZE]
    finally:
        c.close()
    reborn = Core(eeprom=saved, max_rate_hz=200, max_rate_pipeline_hz=150)
    try:
        again = reborn.info()
    finally:
        reborn.close()
    assert again.config_problem == 0 and (again.rate_hz, again.filter_hz) == (rate, filter_hz)
    assert again.zero_counts == info.zero_counts and again.tare == info.tare


def test_the_pipeline_is_refused_at_rates_the_board_cannot_run_it_at(core):
    """A board that filters and transforms at most 250 Hz (its identity says so): the filter
    and a tool frame are refused above that rate, and that rate above them."""
    core.core.set_max_rate_pipeline(250)
    assert core.info().max_rate_pipeline_hz == 250
    for command, args in [(C.SET_FILTER, (20.0,)), (C.SET_TOOL, (0.0, 0.0, 0.01, 0.0, 0.0, 0.0))]:
        nack = core.command(command, *args)
        assert (nack.reason, nack.detail) == (P.NackReason.RATE_TOO_HIGH, 250)
    assert isinstance(core.command(C.SET_TOOL, *[0.0] * 6), P.Ack)    # the identity costs nothing
    assert core.command(C.START, 250).value == 250
    assert isinstance(core.command(C.SET_FILTER, 20.0), P.Ack)
    nack = core.command(C.START, 300)
    assert (nack.reason, nack.detail) == (P.NackReason.RATE_TOO_HIGH, 250)
    core.command(C.SET_FILTER, 0.0)
    assert core.command(C.START, 300).value == 300
