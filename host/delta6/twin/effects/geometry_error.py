"""``geometry_error``: the built mechanism differs from the nominal design (geometry)."""
from __future__ import annotations

from delta6.twin.effects.base import Effect, ParamSpec, Stage
from delta6.twin.statics import rotation_from_vector

_LENGTHS = (("a", "base radius a"), ("b", "platform radius b"),
            ("la", "proximal link length l_a"), ("lb", "parallelogram link length l_b"))


class GeometryError(Effect):
    """Printed parts come out a few tenths of a millimetre off, the threaded rods are cut and
    their ball ends screwed on by hand, the three spring units are placed on the base by
    screw holes, and the 3-DOF unit is pressed onto the platform: every branch ends up with its
    own a, b, l_a, l_b, azimuth and rest angle, and the gimbal sits slightly rotated."""

    NAME = "geometry_error"
    ACTS_ON = (Stage.GEOMETRY,)
    FORMULATIONS = ("rigid",)
    PER_JOINT = False
    SPECS = tuple(
        ParamSpec(f"delta_{key}_mm", "mm", "branch", 0.05, 1.0 if key == "lb" else 0.5,
                  sign="+-", valid=(-5.0, 5.0), doc=f"built minus nominal {what}, per branch")
        for key, what in _LENGTHS) + (
        ParamSpec("delta_azimuth_rad", "rad", "branch", 5e-4, 1e-2, sign="+-",
                  valid=(-0.1, 0.1), doc="built minus nominal branch azimuth phi_i"),
        ParamSpec("delta_rest_angle_rad", "rad", "branch", 5e-4, 1e-2, sign="+-",
                  valid=(-0.1, 0.1), doc="built minus nominal theta_offset (the proximal link "
                                         "angle at zero spring torque), per branch"),
        ParamSpec("gimbal_misalignment_rad", "rad", "vec3", 5e-4, 1e-2, sign="+-",
                  valid=(-0.1, 0.1), doc="rotation vector of the 3-DOF unit's neutral frame "
                                         "{E0} relative to {B}"),
    )

    def geometry(self, geo, sig, torque):
        p = geo.params
        changes = {key: getattr(p, key) + self.p(f"delta_{key}_mm") * 1e-3 for key, _ in _LENGTHS}
        changes["phi"] = p.phi + self.p("delta_azimuth_rad")
        changes["offset"] = p.offset + self.p("delta_rest_angle_rad")
        built = type(geo)(p.with_(**changes), geo.e0_rotation)
        return built.rotated(rotation_from_vector(self.p("gimbal_misalignment_rad")))

    def summary(self):
        return dict(self.params)
