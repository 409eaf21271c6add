"""How the wrench is scaled on the wire, and the check that one encoder count survives it.

Each axis travels as an int16 count of a decimal step (LSB) of 1, 2 or 5 x 10^e N or N*m: the
smallest such step whose +-32767 counts cover 1.25 x the axis's full scale (headroom for loads
beyond the joint box and for tared values; beyond it the value clips and the status says
OVERRANGE). The firmware picks the steps itself from the full scale it is built with
(``delta6_protocol.cpp``, scaleForFullScale); this module mirrors it in float32, bit for bit.

:func:`resolution_check` proves the step fine enough: the smallest change of the wrench that a
one-count step of any encoder causes anywhere in the joint box must move at least one axis by
at least one LSB.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from delta6.core import boxsearch
from delta6.core.design import Design
from delta6.core.model import Params, base_force, base_moment, rotation
from delta6.core.spec import full_scale
from delta6.core.workspace import joint_box
from delta6.link.protocol import COUNT_RAD, INVALID_VALUE, MAX_VALUE, lsb_value

MIN_EXPONENT, MAX_EXPONENT = -6, 3
HEADROOM = 1.25
MANTISSAS = (1, 2, 5)


def choose_scale(full_scale_value: float) -> tuple[int, int]:
    """(mantissa, exponent) of an axis's LSB for a full scale, exactly as the firmware picks
    it (float32 arithmetic, so both agree even when the full scale sits on a boundary)."""
    f32 = np.float32
    needed = f32(full_scale_value) * (f32(HEADROOM) / f32(MAX_VALUE))
    for e in range(MIN_EXPONENT, MAX_EXPONENT + 1):
        decade = f32(f"1e{e}")
        for m in MANTISSAS:
            if f32(m) * decade >= needed:
                return m, e
    return 5, MAX_EXPONENT


def design_lsb(design: Design) -> np.ndarray:
    """The six LSBs (N, N*m) a device built for ``design`` uses."""
    return np.array([lsb_value(*choose_scale(fs)) for fs in full_scale(design)])


def float32_lsb(mantissa: int, exponent: int) -> np.float32:
    """The device's float32 LSB (mantissa times the float32 decade literal)."""
    return np.float32(mantissa) * np.float32(f"1e{exponent}")


def quantize(values, lsb_float32) -> tuple[np.ndarray, np.ndarray]:
    """The firmware's quantisation, in float32 like the device: (counts, clipped); NaN gives
    INVALID_VALUE, values beyond +-32767 LSB clip. For tests and synthetic captures."""
    f32 = np.float32
    inverse = f32(1.0) / np.asarray(lsb_float32, dtype=f32)
    with np.errstate(invalid="ignore", over="ignore"):
        x = np.asarray(values, dtype=f32) * inverse
        clipped = np.abs(x) > f32(MAX_VALUE)
        limited = np.clip(np.nan_to_num(x, nan=0.0), -MAX_VALUE, MAX_VALUE)
        whole = np.trunc(limited)
        frac = limited - whole
        q = whole + (frac >= 0.5) - (frac <= -0.5)
    q = np.where(np.isnan(x), INVALID_VALUE, q).astype(np.int16)
    return q, clipped & ~np.isnan(x)


@dataclass
class ResolutionCheck:
    """One design's wire scaling against its encoder resolution (N and N*m)."""

    full_scale: np.ndarray      # per axis
    lsb: np.ndarray             # per axis
    force_step_min: float       # smallest ||dF|| from one count of joints 1..3 over the box
    moment_step_min: float      # smallest ||dM|| from one count of joints 4..6 over the box

    @property
    def force_margin(self) -> float:
        """How many of the coarsest force LSB the largest axis of the smallest step spans
        (at least ||dF|| / sqrt(3)); >= 1 means no count is lost."""
        return self.force_step_min / np.sqrt(3) / self.lsb[:3].max()

    @property
    def moment_margin(self) -> float:
        return self.moment_step_min / np.sqrt(3) / self.lsb[3:].max()

    @property
    def headroom(self) -> np.ndarray:
        return MAX_VALUE * self.lsb / self.full_scale


def resolution_check(design: Design) -> ResolutionCheck:
    """The smallest one-count change over the joint box, for the forces from joints 1..3
    (||dF|| does not depend on joints 4..6: they only rotate it) and the moments from joints
    4..6. A count of joints 4..6 also turns the force, by |F| x 3.8e-4: at no load that is no
    change at all, which no scaling can or needs to show."""
    p = Params.from_design(design)
    lo, hi = joint_box(design, 3)

    def bumped(t, j):
        out = np.array(t, dtype=float, copy=True)
        out[:, j] += COUNT_RAD
        return out

    def moment(t):
        return np.einsum("nji,nj->ni", rotation(t), base_moment(p, t))

    force_min = min(boxsearch.minimize(
        lambda t, j=j: np.linalg.norm(base_force(p, bumped(t, j)) - base_force(p, t), axis=-1),
        lo, hi)[0] for j in range(3))
    moment_min = min(boxsearch.minimize(
        lambda t, j=j: np.linalg.norm(moment(bumped(t, j)) - moment(t), axis=-1),
        lo, hi)[0] for j in range(3))
    return ResolutionCheck(full_scale=full_scale(design), lsb=design_lsb(design),
                           force_step_min=force_min, moment_step_min=moment_min)
