"""``joint_friction``: friction opposing joint motion (torque side)."""
from __future__ import annotations

import numpy as np

from delta6.core.operators import affine_scan
from delta6.twin.effects.base import Effect, ParamSpec, Stage

#: Speeds over which the formulation-independent Coulomb and viscous equivalents are fitted.
FIT_SPEEDS_RAD_S = np.linspace(0.05, 0.5, 10)
REF_SPEED_RAD_S = 0.1


class JointFriction(Effect):
    """The shafts turn in small ball bearings and every link ends in a plastic ball joint: a
    torque that opposes the joint's motion, almost constant in speed (Coulomb) with a part
    growing with speed (viscous, grease and the plastic's damping). 'coulomb_viscous' uses a
    smooth sign; 'stribeck' adds the higher breakaway torque at low speed; 'lugre' is the
    dynamic LuGre model, with bristles that deflect before sliding (pre-sliding)."""

    NAME = "joint_friction"
    ACTS_ON = (Stage.TORQUE,)
    FORMULATIONS = ("coulomb_viscous", "stribeck", "lugre")
    SPECS = (
        ParamSpec("coulomb_nm", "N*m", "joint", 5e-4, 8e-3, valid=(0.0, 0.5),
                  doc="sliding (Coulomb) friction torque"),
        ParamSpec("viscous_nm_s_per_rad", "N*m*s/rad", "joint", 2e-4, 5e-3, valid=(0.0, 1.0),
                  doc="viscous friction coefficient"),
        ParamSpec("smoothing_rad_s", "rad/s", "joint", 0.002, 0.01, primary=False,
                  valid=(1e-6, 1.0), formulations=("coulomb_viscous", "stribeck"),
                  doc="speed scale of the smooth sign tanh(w / this)"),
        ParamSpec("static_ratio", "1", "joint", 1.1, 2.0, primary=False, valid=(1.0, 10.0),
                  formulations=("stribeck", "lugre"), doc="breakaway / Coulomb torque"),
        ParamSpec("stribeck_rad_s", "rad/s", "joint", 0.005, 0.05, primary=False,
                  valid=(1e-6, 10.0), formulations=("stribeck", "lugre"),
                  doc="Stribeck speed: the breakaway excess decays as exp(-(w / this)^2)"),
        ParamSpec("bristle_nm_per_rad", "N*m/rad", "joint", 2.0, 20.0, primary=False,
                  valid=(1e-3, 1e4), formulations=("lugre",),
                  doc="LuGre bristle stiffness sigma0 (pre-sliding angle ~ Coulomb / this)"),
    )

    def _sliding(self, speed: np.ndarray) -> np.ndarray:
        """Magnitude of the sliding friction (without the viscous part) at |speed|."""
        coulomb = self.p("coulomb_nm")
        if self.formulation == "coulomb_viscous":
            return np.broadcast_to(coulomb, np.shape(speed))
        excess = (self.p("static_ratio") - 1.0) * coulomb
        return coulomb + excess * np.exp(-(np.asarray(speed) / self.p("stribeck_rad_s")) ** 2)

    def steady_state(self, speed: np.ndarray) -> np.ndarray:
        """Friction torque at constant joint speed (rad/s, broadcast against the joints)."""
        speed = np.asarray(speed, dtype=float)
        viscous = self.p("viscous_nm_s_per_rad") * speed
        if self.formulation == "lugre":
            return self._sliding(np.abs(speed)) * np.sign(speed) + viscous
        return self._sliding(np.abs(speed)) * np.tanh(speed / self.p("smoothing_rad_s")) + viscous

    def extra_torque(self, sig):
        if self.formulation != "lugre":
            return self.steady_state(sig.qd)
        # LuGre: dz/dt = w - sigma0 |w| z / g(w), tau = sigma0 z + viscous w; with w constant
        # over a step the bristle state relaxes exactly (exponentially in angle).
        step = np.diff(sig.q, axis=0, prepend=sig.q[:1])
        speed = step / sig.dt if sig.dt > 0 else np.zeros_like(step)
        sliding = self._sliding(np.abs(speed))
        sigma0 = self.p("bristle_nm_per_rad")
        slides = sliding > 0
        rate = np.divide(sigma0 * np.abs(step), sliding, out=np.zeros_like(step), where=slides)
        a = np.where(slides, np.exp(-rate), 1.0)
        bristle = affine_scan(a, np.sign(step) * sliding / sigma0 * (1.0 - a), np.zeros(6))
        return sigma0 * bristle + self.p("viscous_nm_s_per_rad") * sig.qd

    def summary(self):
        speeds = FIT_SPEEDS_RAD_S[:, None]
        curve = self.steady_state(np.repeat(speeds, 6, axis=1))
        design = np.stack([np.ones_like(FIT_SPEEDS_RAD_S), FIT_SPEEDS_RAD_S], axis=1)
        (intercept, slope), *_ = np.linalg.lstsq(design, curve, rcond=None)
        return {
            "coulomb_equiv_nm": intercept,
            "viscous_equiv_nm_s_per_rad": slope,
            "torque_at_ref_speed_nm": self.steady_state(np.full(6, REF_SPEED_RAD_S)),
            "ref_speed_rad_s": REF_SPEED_RAD_S,
            "breakaway_nm": self._sliding(np.zeros(6)),
        }
