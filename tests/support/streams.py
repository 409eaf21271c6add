"""Streams of valid frames for decoder tests and benchmarks (Python encoders)."""
from __future__ import annotations

import random

from delta6.link import protocol as P


def make_frames(n: int, seed: int = 0, data_only: bool = False) -> tuple[list[bytes], list]:
    """n frames (each ending in 0x00) and the record each carries. Data records get consecutive
    sequence numbers; a sprinkling of answers, telemetry and events lies between them."""
    rnd = random.Random(seed)
    frames, records = [], []
    seq = rnd.randrange(65536)
    t = rnd.randrange(2**32)
    for _ in range(n):
        kind = rnd.random()
        if data_only or kind < 0.85:
            wrench = tuple(rnd.randrange(-32768, 32768) if rnd.random() < 0.3 else
                           rnd.randrange(-300, 300) for _ in range(6))
            counts = (tuple(rnd.randrange(16384) for _ in range(6))
                      if rnd.random() < 0.2 else None)
            status = rnd.choice([0, 0, 0, P.Status.TARE_ACTIVE, P.Status.ENCODER1 | P.Status.WRENCH_INVALID,
                                 P.Status.OVERRANGE])
            record = P.WrenchRecord(seq, t, status, wrench, counts)
            frame = P.encode_wrench(seq, t, status, wrench, counts)
            seq = (seq + 1) & 0xFFFF
            t = (t + 1000) & 0xFFFFFFFF
        elif kind < 0.9:
            record = P.Ack(rnd.randrange(1, 256), P.Command.PING, rnd.randrange(2**32))
            frame = P.encode_ack(*record)
        elif kind < 0.95:
            record = P.Nack(rnd.randrange(1, 256), P.Command.START, P.NackReason.RATE_TOO_HIGH, 2000)
            frame = P.encode_nack(*record)
        else:
            # Not BOOT: that one says the counters start again, which these do not.
            record = P.Event(P.EventCode.CONFIG_DEFAULTS, rnd.randrange(1, 5))
            frame = P.encode_event(*record)
        frames.append(frame)
        records.append(record)
    return frames, records


def an_info(**changes) -> P.Info:
    """A usable 1.3 INFO record (the baseline's identity, 250 Hz), with ``changes``."""
    base = P.Info(request_id=0, protocol=P.VERSION, firmware=(1, 0, 0), mode=1,
                  design_hash=0x535534AF, design_name="delta6", full_scale=(1.0,) * 6,
                  lsb_mantissa=(1,) * 6, lsb_exponent=(-3,) * 6, rate_hz=250, max_rate_hz=350,
                  status=0, streaming=False, config_problem=0, baud=500000, serial_number=0,
                  zero_counts=(0,) * 6, tare=(0.0,) * 6, joint_limit_rad=0.5, boot_id=1,
                  max_rate_pipeline_hz=250)
    return base._replace(**changes)
