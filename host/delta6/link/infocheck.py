"""Whether a device-info record can be trusted: every field the host uses to turn counts into
newtons and angles must be a value the protocol allows (docs/protocol.md, INFO).

An INFO record with a valid CRC can still be unusable: a device of another protocol major
version, or a record built by something that is not a Delta6. Scaling wrench counts with a
mantissa of 3 would make up every value of a log, so such a record is refused, not used.
"""
from __future__ import annotations

import math

from delta6.link.protocol import COUNTS_PER_TURN, VERSION, Info, Mode
from delta6.link.wirescale import MANTISSAS, MAX_EXPONENT, MIN_EXPONENT


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
    return None
