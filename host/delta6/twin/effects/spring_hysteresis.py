"""``spring_hysteresis``: rate-independent hysteresis of the spring torque (torque side)."""
from __future__ import annotations

import numpy as np

from delta6.core.operators import affine_scan, play
from delta6.twin.effects.base import Effect, ParamSpec, Stage

#: Play operators of the 'play_sum' formulation (radii evenly spaced up to the saturation
#: angle, equal weights).
PLAYS = 6


class SpringHysteresis(Effect):
    """A torsion spring's coils rub on each other and on the shaft, and its legs slide on the
    printed clips: loading and unloading follow different curves, and the loop depends on where
    the joint has been, not on how fast it got there (the paper's Fig. 6-b shows a symmetric
    loop on joint 6). 'bouc_wen' is the differential Bouc-Wen model with n = 1 and gamma = 0
    (Dahl): after a reversal the hysteretic torque approaches the other branch exponentially in
    angle. 'play_sum' is a Prandtl-Ishlinskii (Preisach-type) sum of play operators: the loop
    is piecewise linear and saturates after a finite travel."""

    NAME = "spring_hysteresis"
    ACTS_ON = (Stage.TORQUE,)
    FORMULATIONS = ("bouc_wen", "play_sum")
    SPECS = (
        ParamSpec("half_width_nm", "N*m", "joint", 0.002, 0.02, valid=(0.0, 0.5),
                  doc="half-width of the saturated loop: the hysteretic torque lies in +-this"),
        ParamSpec("reversal_angle_rad", "rad", "joint", 0.01, 0.06, primary=False,
                  valid=(1e-4, 1.0), formulations=("bouc_wen",),
                  doc="angle constant of the exponential approach after a reversal"),
        ParamSpec("saturation_angle_rad", "rad", "joint", 0.02, 0.12, primary=False,
                  valid=(1e-4, 1.0), formulations=("play_sum",),
                  doc="largest play radius: the loop saturates after twice this travel"),
    )

    def hysteretic_torque(self, q: np.ndarray) -> np.ndarray:
        """The hysteretic torque (N*m) along a path of joint angles q (M, 6), from a virgin
        (demagnetised-like) state at q[0]."""
        width = self.p("half_width_nm")
        if self.formulation == "bouc_wen":
            # dz/dq = (H / phi0) (1 - sign(dq) z / H), integrated exactly over each step.
            step = np.diff(q, axis=0, prepend=q[:1])
            a = np.exp(-np.abs(step) / self.p("reversal_angle_rad"))
            return affine_scan(a, width * np.sign(step) * (1.0 - a), np.zeros(q.shape[1]))
        radii = self.p("saturation_angle_rad")[None, :] * np.arange(1, PLAYS + 1)[:, None] / PLAYS
        weight = width / radii.sum(axis=0)                       # saturated sum = H
        stops = q[:, None, :] - play(q[:, None, :], radii)
        return weight * stops.sum(axis=1)

    def extra_torque(self, sig):
        return self.hysteretic_torque(sig.q)

    def summary(self):
        # Travel after a reversal from saturation at which the loop has covered 90 % of its
        # swing: a shape measure that does not depend on the formulation.
        travel = np.linspace(0.0, 1.0, 4001)
        path = np.concatenate([-travel, travel[1:] - 1.0])
        torque = self.hysteretic_torque(np.repeat(path[:, None], 6, axis=1))
        width = self.p("half_width_nm")
        back = torque[len(travel) - 1:]
        with np.errstate(invalid="ignore", divide="ignore"):
            swing = (back - back[0]) / (2 * width)
        reached = np.argmax(swing >= 0.9, axis=0)
        return {"half_width_nm": width,
                "reversal_angle_90_rad": np.where(width > 0, travel[reached], 0.0)}
