"""``encoder_periodic_error``: the magnetic encoder's error periodic in its shaft angle
(angle side)."""
from __future__ import annotations

import numpy as np

from delta6.twin.effects.base import Effect, ParamSpec, Stage

#: Harmonics of the 'harmonics' formulation and their relative sizes (1/h).
HARMONICS = (1, 2, 3, 4)
#: Range over which the peak-to-peak error is summarised, rad (about the joint box).
SUMMARY_RANGE_RAD = 0.5


class EncoderPeriodicError(Effect):
    """A diametric magnet glued on a printed shaft is never exactly centred nor square to the
    sensor: the angle the chip reports is off by an error that repeats every turn of the shaft
    (magnet eccentricity gives the first harmonic, a tilted or non-uniform field the second,
    the chip's own interpolation higher ones). The encoder is zeroed at the joint's rest angle,
    so the error is zero there. 'eccentricity': first and second harmonics; 'harmonics':
    harmonics 1..4 with sizes falling as 1/h. ``mount_angle_rad`` is where on the turn the
    joint's rest angle lies (the phase of the error)."""

    NAME = "encoder_periodic_error"
    ACTS_ON = (Stage.ANGLE,)
    FORMULATIONS = ("eccentricity", "harmonics")
    ORDER = 20   # a readout error of the chip itself
    SPECS = (
        ParamSpec("amplitude_rad", "rad", "joint", 1e-3, 1.5e-2, valid=(0.0, 0.1),
                  doc="amplitude of the first harmonic of the error over a shaft turn"),
        ParamSpec("second_ratio", "1", "joint", 0.1, 0.6, primary=False, valid=(0.0, 2.0),
                  formulations=("eccentricity",),
                  doc="amplitude of the second harmonic relative to the first"),
        ParamSpec("mount_angle_rad", "rad", "joint", 0.05, 6.28, primary=False,
                  valid=(-10.0, 10.0), doc="shaft angle of the joint's rest position"),
    )

    def _harmonics(self):
        a = self.p("amplitude_rad")
        if self.formulation == "eccentricity":
            return [(1, a, 0.0), (2, a * self.p("second_ratio"), 0.9)]
        return [(h, a / h, 0.7 * h) for h in HARMONICS]

    def error(self, q: np.ndarray) -> np.ndarray:
        """Encoder error (rad) at joint angles q, zero at q = 0."""
        phi = self.p("mount_angle_rad")
        out = np.zeros_like(q)
        for h, amp, phase in self._harmonics():
            out = out + amp * (np.sin(h * (q + phi) + phase) - np.sin(h * phi + phase))
        return out

    def encoder(self, angle, sig):
        return angle + self.error(angle)

    def summary(self):
        q = np.linspace(-SUMMARY_RANGE_RAD, SUMMARY_RANGE_RAD, 501)[:, None] * np.ones(6)
        err = self.error(q)
        return {"amplitude_rad": self.p("amplitude_rad"),
                "peak_to_peak_rad": err.max(axis=0) - err.min(axis=0),
                "range_rad": SUMMARY_RANGE_RAD}
