"""``link_compliance``: the printed links deform elastically under load (geometry)."""
from __future__ import annotations

import numpy as np

from delta6.twin import statics
from delta6.twin.effects.base import Effect, ParamSpec, Stage
from delta6.twin.statics import rotation_from_vector

#: Loads at which the compliances are stated (and the Hertzian law matches the linear one).
REF_FORCE_N = 5.0
REF_MOMENT_NM = 0.1


def _deflection(compliance, load, ref, formulation):
    """Deflection for a signed load: linear, or Hertzian contact (delta ~ |load|^(2/3)),
    both giving compliance * ref at the reference load."""
    if formulation == "linear":
        return compliance * load
    return compliance * ref * np.sign(load) * (np.abs(load) / ref) ** (2.0 / 3.0)


class LinkCompliance(Effect):
    """The proximal links are PLA cantilevers a few millimetres thick, the rods end in plastic
    ball joints and the platform hangs on them: under load the elbows move with the link force,
    the rods stretch or shorten, and the platform carrying the 3-DOF unit tilts under the
    moment. The kinematics then no longer follows the encoder angles. 'hertzian' lets the
    ball-joint contacts stiffen with load (deflection ~ load^(2/3))."""

    NAME = "link_compliance"
    ACTS_ON = (Stage.GEOMETRY,)
    FORMULATIONS = ("linear", "hertzian")
    PER_JOINT = False
    ORDER = 10   # after the static geometry: it deforms the built mechanism
    SPECS = (
        ParamSpec("elbow_mm_per_n", "mm/N", "branch", 0.01, 0.15, valid=(0.0, 1.0),
                  doc="proximal link tip deflection per N of force across the link "
                      f"(at {REF_FORCE_N:g} N)"),
        ParamSpec("rod_mm_per_n", "mm/N", "branch", 0.001, 0.02, valid=(0.0, 0.5),
                  doc=f"parallelogram link stretch per N of tension (at {REF_FORCE_N:g} N)"),
        ParamSpec("tilt_rad_per_nm", "rad/(N*m)", "scalar", 0.005, 0.08, valid=(0.0, 1.0),
                  doc="platform tilt per N*m of moment about the platform centre "
                      f"(at {REF_MOMENT_NM:g} N*m)"),
    )

    def geometry(self, geo, sig, torque):
        f = self.formulation
        p = geo.params
        # The elbow moves across the link with the force that makes the joint torque: an extra
        # rotation of the link's geometry in series with the spring.
        across = torque[..., :3] / p.la
        bend = _deflection(self.p("elbow_mm_per_n") * 1e-3, across, REF_FORCE_N, f) / p.la
        bent = type(geo)(p.with_(offset=p.offset + bend), geo.e0_rotation)
        # The links stretch with their tension, which depends on the geometry: two passes.
        lb0 = p.lb
        stretched = bent
        for _ in range(2):
            tension = statics.link_tension(stretched, sig.q, torque)
            stretch = _deflection(self.p("rod_mm_per_n") * 1e-3, tension, REF_FORCE_N, f)
            stretched = type(geo)(bent.params.with_(lb=lb0 + stretch), geo.e0_rotation)
        # The platform tilts with the moment about its centre: the gimbal's moment plus the
        # force acting at {E}, a distance c below the platform centre.
        force = statics.base_force(stretched, sig.q, torque)
        lever = np.array([0.0, 0.0, p.c])
        moment = torque[..., 3:] + np.cross(lever, force)
        size = np.linalg.norm(moment, axis=-1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            direction = np.where(size > 0, moment / size, 0.0)
        tilt = _deflection(self.p("tilt_rad_per_nm"), size, REF_MOMENT_NM, f) * direction
        return stretched.rotated(rotation_from_vector(tilt))

    def summary(self):
        return {
            "elbow_mm_at_ref_force": self.p("elbow_mm_per_n") * REF_FORCE_N,
            "rod_mm_at_ref_force": self.p("rod_mm_per_n") * REF_FORCE_N,
            "tilt_rad_at_ref_moment": self.p("tilt_rad_per_nm") * REF_MOMENT_NM,
            "ref_force_n": REF_FORCE_N, "ref_moment_nm": REF_MOMENT_NM,
            "elbow_mm_per_n": self.p("elbow_mm_per_n"), "rod_mm_per_n": self.p("rod_mm_per_n"),
            "tilt_rad_per_nm": self.p("tilt_rad_per_nm"),
        }
