"""The true plant: from the joint motion the robot imposes to the true wrench and to the angles
the encoders see, with the active effects applied at their stages, in this fixed order:

1. TORQUE   joint torque = spring rate (x every ``spring_scale``) * q + every ``extra_torque``
2. GEOMETRY the built mechanism (static deltas, then load-dependent deformation)
3. statics  the wrench at {E} that balances those torques in that mechanism (``statics``)
4. TIME     what the reference sensor sees of that wrench, and when
5. ANGLE    what the encoders read of the joint angles (mechanical play, then readout errors)

The joint torques and the encoder angles run on the fine time grid of the simulation (the
history-dependent effects use the blocked scans of ``delta6.core.operators``). The statics is
history-free: it runs on the samples the caller keeps, unless a TIME effect needs the wrench
between them; in chunks, so that long runs can report progress.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from delta6.twin.effects import Effect, Signals, Stage
from delta6.twin.fields import number
from delta6.twin.statics import PlantGeometry, plant_wrench

MAX_OVERSAMPLE = 64


def check_oversample(oversample) -> int:
    """Plant steps per logged sample: a whole number in 1..MAX_OVERSAMPLE."""
    return number("oversample", oversample, 1, MAX_OVERSAMPLE, integer=True)


#: Fine samples per statics chunk (bounds memory, paces the progress display).
CHUNK = 50_000


@dataclass
class PlantOutput:
    torque: np.ndarray      # (M, 6) true joint torques, N*m
    wrench: np.ndarray      # (N, 6) true wrench at {E}, at the kept samples
    reference: np.ndarray   # (N, 6) the wrench as the reference sensor reports it (no noise)
    encoder: np.ndarray     # (M, 6) encoder angles before quantization, rad


def at_stage(effects: Sequence[Effect], stage: Stage) -> list[Effect]:
    return sorted((e for e in effects if stage in e.ACTS_ON), key=lambda e: e.ORDER)


def joint_torque(effects: Sequence[Effect], sig: Signals) -> np.ndarray:
    """Stage 1: spring torques with the spring-side effects."""
    rate = np.broadcast_to(np.asarray(sig.nominal.k, dtype=float), sig.q.shape)
    extra = np.zeros_like(sig.q)
    for e in at_stage(effects, Stage.TORQUE):
        rate = rate * e.spring_scale(sig)
        extra = extra + e.extra_torque(sig)
    return rate * sig.q + extra


def true_wrench(effects: Sequence[Effect], sig: Signals, torque: np.ndarray,
                progress: Callable[[float], None] | None = None) -> np.ndarray:
    """Stages 2-3, chunk by chunk (both are history-free)."""
    geometric = at_stage(effects, Stage.GEOMETRY)
    out = np.empty_like(torque)
    n = len(torque)
    for start in range(0, n, CHUNK):
        part = slice(start, min(n, start + CHUNK))
        piece = sig.rows(part)
        geo = PlantGeometry(sig.nominal)
        for e in geometric:
            geo = e.geometry(geo, piece, torque[part])
        out[part] = plant_wrench(geo, piece.q, torque[part])
        if progress:
            progress(part.stop / n)
    return out


def run(effects: Sequence[Effect], sig: Signals, keep: np.ndarray,
        progress: Callable[[float], None] | None = None) -> PlantOutput:
    """The plant on the fine grid ``sig``; the wrench and the reference at the samples ``keep``
    (indices into the fine grid) only."""
    torque = joint_torque(effects, sig)
    timed = at_stage(effects, Stage.TIME)
    if timed:   # the sensor sees the wrench between the kept samples too
        wrench = true_wrench(effects, sig, torque, progress)
        reference = wrench
        for e in timed:
            reference = e.reference(reference, sig)
        wrench, reference = wrench[keep], reference[keep]
    else:
        wrench = reference = true_wrench(effects, sig.rows(keep), torque[keep], progress)
    encoder = sig.q
    for e in at_stage(effects, Stage.ANGLE):
        encoder = e.encoder(encoder, sig)
    return PlantOutput(torque=torque, wrench=wrench, reference=reference, encoder=encoder)
