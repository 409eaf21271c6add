"""``harness``: a cable or harness between the base and the tool plate, an elastic path in
parallel with the springs (torque side)."""
from __future__ import annotations

import numpy as np

from delta6.core import model
from delta6.twin.effects.base import Effect, ParamSpec, Stage

#: Displacement at which the harness force is stated, m.
REF_DISPLACEMENT_M = 0.01
_STEP = 1e-6


class Harness(Effect):
    """The tool's cable (or a sensor harness) runs from the base to the tool plate: as the plate
    moves it bends and stretches the cable, which pulls on the plate with a force that depends
    on where the plate is, in parallel with the springs. The robot's wrench is shared between
    the springs and the cable, so the encoders see less deflection than the model expects. The
    cable is clamped at a point off the plate's centre, so its force also turns the gimbal.
    'linear': a force growing linearly with the displacement from rest, stiffer along one
    direction than the others, plus a preload; 'cable': a slack cable to an anchor on the
    base that only pulls once taut, ever harder as it stretches."""

    NAME = "harness"
    ACTS_ON = (Stage.TORQUE,)
    FORMULATIONS = ("linear", "cable")
    PER_JOINT = False
    SPECS = (
        ParamSpec("stiffness_n_per_mm", "N/mm", "scalar", 0.005, 0.08, valid=(0.0, 10.0),
                  doc="force per mm of plate displacement (along the stiff direction; at "
                      f"{REF_DISPLACEMENT_M * 1e3:g} mm of stretch for 'cable')"),
        ParamSpec("direction", "1", "vec3", 0.2, 1.0, sign="+-", primary=False,
                  valid=(-1.0, 1.0), doc="stiff direction (linear) or anchor direction (cable) "
                                         "in {B}, normalised"),
        ParamSpec("preload_n", "N", "vec3", 0.01, 0.1, sign="+-", primary=False,
                  valid=(-5.0, 5.0), formulations=("linear",), doc="force at rest, {B}"),
        ParamSpec("attach_offset_mm", "mm", "scalar", 5.0, 30.0, primary=False,
                  valid=(0.0, 100.0), doc="clamp point's distance from the plate centre"),
    )

    def _unit(self) -> np.ndarray:
        d = self.p("direction")
        return d / max(np.linalg.norm(d), 1e-12)

    def _clamp(self, nominal, q: np.ndarray) -> np.ndarray:
        """Clamp point in {B} (m): the plate centre plus the offset turned by the gimbal."""
        offset = np.array([self.p("attach_offset_mm") * 1e-3, 0.0, 0.0])
        rot = model.rotation(q[..., 3:])
        return model.forward_kinematics(nominal, q[..., :3]) + rot @ offset

    def force(self, displacement: np.ndarray) -> np.ndarray:
        """Harness force on the plate (N, {B}) for clamp displacements from rest (m)."""
        k = self.p("stiffness_n_per_mm") * 1e3
        u = self._unit()
        along = displacement @ u
        if self.formulation == "linear":
            # Stiff along u, a third of that across it.
            across = displacement - along[..., None] * u
            return -(k * along[..., None] * u + k / 3 * across) + self.p("preload_n")
        # Anchor far along -u: the cable stretches as the clamp moves along +u, taut once
        # past a slack of a quarter of the reference displacement.
        slack = 0.25 * REF_DISPLACEMENT_M
        stretch = np.maximum(along - slack, 0.0)
        scale = REF_DISPLACEMENT_M - slack
        return -(k * REF_DISPLACEMENT_M * (stretch / scale) ** 1.5)[..., None] * u

    def extra_torque(self, sig):
        q = sig.q
        rest = self._clamp(sig.nominal, np.zeros(6))
        here = self._clamp(sig.nominal, q)
        f = self.force(here - rest)
        # Virtual work: the joint torques that balance a force at the clamp are J^T f, with J
        # the clamp's motion per joint angle.
        torque = np.empty_like(q)
        for j in range(6):
            step = np.zeros(6)
            step[j] = _STEP
            moved = (self._clamp(sig.nominal, q + step) - here) / _STEP
            torque[:, j] = np.einsum("mi,mi->m", moved, f)
        return torque

    def summary(self):
        u = self._unit()
        return {"stiffness_n_per_mm": self.p("stiffness_n_per_mm"),
                "force_at_ref_n": float(np.linalg.norm(self.force(REF_DISPLACEMENT_M * u))),
                "ref_displacement_m": REF_DISPLACEMENT_M}
