"""``encoder_offset``: each encoder reads its joint angle plus a constant (angle side)."""
from __future__ import annotations

from delta6.twin.effects.base import Effect, ParamSpec, Stage


class EncoderOffset(Effect):
    """The encoder's zero is not the spring's rest angle: the magnet is glued on at an arbitrary
    angle and zeroed once, with the tool hanging on the device and the antagonistic spring
    clips set by hand, so the zero misses the true rest angle by a fraction of a degree."""

    NAME = "encoder_offset"
    ACTS_ON = (Stage.ANGLE,)
    FORMULATIONS = ("constant",)
    ORDER = 10   # a readout error: after the mechanical play
    SPECS = (
        ParamSpec("offset_rad", "rad", "joint", 5e-4, 1.5e-2, sign="+-", valid=(-0.2, 0.2),
                  doc="encoder reading minus true joint deflection"),
    )

    def encoder(self, angle, sig):
        return angle + self.p("offset_rad")

    def summary(self):
        return {"offset_rad": self.p("offset_rad")}
