"""``nonlinear_spring``: the spring rate changes with the deflection (torque side)."""
from __future__ import annotations

import numpy as np

from delta6.twin.effects.base import Effect, ParamSpec, Stage

#: Deflection at which the rate change is stated (about the joint limit of the printed design).
REF_ANGLE_RAD = 0.5


class NonlinearSpring(Effect):
    """A torsion spring's legs bear on printed clips that bend as the deflection grows, and the
    coils close up on the shaft: the antagonistic pair stiffens towards the ends of its travel
    (a door-handle spring is not made for precision). 'cubic': tau = k q (1 + s (q / q_ref)^2),
    a smooth stiffening; 'progressive': nothing until a knee, then a stiffening that grows
    with the square of the travel beyond it (a clip that starts to bear). Both add the
    fraction ``stiffening`` of the nominal torque at the reference deflection q_ref."""

    NAME = "nonlinear_spring"
    ACTS_ON = (Stage.TORQUE,)
    FORMULATIONS = ("cubic", "progressive")
    SPECS = (
        ParamSpec("stiffening", "1", "joint", 0.01, 0.12, valid=(-0.9, 5.0),
                  doc=f"extra torque at {REF_ANGLE_RAD:g} rad as a fraction of the nominal "
                      "spring torque there"),
        ParamSpec("knee_fraction", "1", "joint", 0.2, 0.7, primary=False, valid=(0.0, 0.95),
                  formulations=("progressive",),
                  doc="deflection where the stiffening starts, as a fraction of the reference"),
    )

    def extra_torque_at(self, q: np.ndarray, k: np.ndarray) -> np.ndarray:
        s = self.p("stiffening")
        if self.formulation == "cubic":
            return k * s * q * (q / REF_ANGLE_RAD) ** 2
        knee = self.p("knee_fraction") * REF_ANGLE_RAD
        beyond = np.maximum(np.abs(q) - knee, 0.0) / (REF_ANGLE_RAD - knee)
        return k * s * REF_ANGLE_RAD * np.sign(q) * beyond ** 2

    def extra_torque(self, sig):
        return self.extra_torque_at(sig.q, np.asarray(sig.nominal.k, dtype=float))

    def summary(self):
        return {"stiffening": self.p("stiffening"), "ref_angle_rad": REF_ANGLE_RAD}
