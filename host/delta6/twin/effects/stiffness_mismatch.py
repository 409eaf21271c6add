"""``stiffness_mismatch``: each joint's spring rate differs from the nominal k (torque side)."""
from __future__ import annotations

from delta6.twin.effects.base import Effect, ParamSpec, Stage


class StiffnessMismatch(Effect):
    """Commodity torsion springs are sold with a rate tolerance of about +-10 %, and each joint
    pairs two of them; the paper calibrated k on joint 6 only, so the other joints keep their
    own rates while the model uses one k for all."""

    NAME = "stiffness_mismatch"
    ACTS_ON = (Stage.TORQUE,)
    FORMULATIONS = ("linear",)
    SPECS = (
        ParamSpec("deviation", "1", "joint", 0.01, 0.12, sign="+-", valid=(-0.5, 0.5),
                  doc="true spring rate / nominal k - 1"),
    )

    def spring_scale(self, sig):
        return 1.0 + self.p("deviation")

    def summary(self):
        return {"ratio": 1.0 + self.p("deviation")}
