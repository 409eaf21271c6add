"""Whether a device-info record can be trusted: every field the host uses to turn counts into
newtons and angles must be a value the protocol allows (docs/protocol.md, INFO).

An INFO record with a valid CRC can still be unusable: a device of another protocol major
version, or a record built by something that is not a Delta6. Scaling wrench counts with a
mantissa of 3 would make up every value of a log, so such a record is refused, not used.
"""
from __future__ import annotations

import math

import numpy as np

from delta6.core.design import MIN_JOINT_LIMIT_RAD
from delta6.core.lowpass import MAX_CUTOFF_RATIO
from delta6.link.protocol import (
    COUNTS_PER_TURN,
    MAX_VALUE,
    TOOL_MAX_ANGLE_RAD,
    TOOL_MAX_TRANSLATION_M,
    VERSION,
    Info,
    Mode,
)
from delta6.link.wirescale import MANTISSAS, MAX_EXPONENT, MIN_EXPONENT

_NAMES = {"design_name": "design", "calibration_name": "calibration", "model_name": "model"}


def _within(value: float, bound: float) -> bool:
    # The device sends float32: a bound it accepts may arrive rounded up by half an ulp.
    return bool(np.float32(value) <= np.float32(bound))


def info_problem(info: Info) -> str | None:
    """What makes ``info`` unusable, in words, or None when every field is in range."""
    major = info.protocol[0]
    if major != VERSION[0]:
        side = "host" if major > VERSION[0] else "firmware"
        return (f"protocol {info.protocol_version}; this delta6 reads {VERSION[0]}.x: "
                f"update the {side}")
    for axis, (m, e) in enumerate(zip(info.lsb_mantissa, info.lsb_exponent)):
        if m not in MANTISSAS or not MIN_EXPONENT <= e <= MAX_EXPONENT:
            return (f"axis {axis + 1} has a wrench step of {m}e{e}, which is not 1, 2 or 5 "
                    f"x 10^{MIN_EXPONENT}..10^{MAX_EXPONENT}")
    if info.mode not in tuple(Mode):
        return f"stream mode {info.mode} is not one of {', '.join(str(int(m)) for m in Mode)}"
    if any(not 0 <= c < COUNTS_PER_TURN for c in info.zero_counts):
        return "a zero count lies outside 0..16383"
    if not all(math.isfinite(v) for v in (*info.tare, *info.full_scale, info.joint_limit_rad)):
        return "a tare offset, full scale or joint limit is not a finite number"
    if any(v <= 0 for v in info.full_scale):
        return "a full-scale value is not positive"
    for key, what in _NAMES.items():
        # Names go into log headers and onto the terminal: printable ASCII, as the doc says.
        name = getattr(info, key)
        if not (name.isascii() and name.isprintable()):
            return f"the {what} name {ascii(name)} is not printable ASCII"
    limit = info.joint_limit_rad
    # Both bounds at float32: a limit just below pi/2 arrives as float32(pi/2), above pi/2.
    if not (_within(MIN_JOINT_LIMIT_RAD, limit) and _within(limit, math.pi / 2)):
        return (f"joint limit {limit:g} rad lies outside a design's "
                f"[{MIN_JOINT_LIMIT_RAD:g}, pi/2)")
    if not (math.isfinite(info.filter_hz) and info.filter_hz >= 0
            and _within(info.filter_hz, MAX_CUTOFF_RATIO * info.max_rate_hz)):
        return (f"low-pass cutoff {info.filter_hz:g} Hz is not 0 (off) or a cutoff the board's "
                f"highest rate allows")
    if not all(math.isfinite(v) and _within(abs(v), TOOL_MAX_TRANSLATION_M)
               for v in info.tool_translation) or not all(
            math.isfinite(v) and _within(abs(v), TOOL_MAX_ANGLE_RAD) for v in info.tool_rpy):
        return (f"tool frame {(*info.tool_translation, *info.tool_rpy)} is not finite or not "
                f"within {TOOL_MAX_TRANSLATION_M:g} m and {TOOL_MAX_ANGLE_RAD:.4g} rad")
    if any(not 0 <= c <= MAX_VALUE for c in info.limits):
        return f"an overload limit lies outside 0..{MAX_VALUE} counts"
    return None
