"""``backlash``: lost motion between a link and its encoder (angle side)."""
from __future__ import annotations

import numpy as np

from delta6.core.operators import play
from delta6.twin.effects.base import Effect, ParamSpec, Stage

#: Contact points of the 'elastic_contact' formulation (clearances spread around the mean).
CONTACTS = 5


class Backlash(Effect):
    """The encoder magnet sits in a printed holder on the end of the link's shaft, a press fit
    that loosens with use: the holder has a little play on the shaft and is held by its own
    drag. After a reversal the link (and its spring) turns while the encoder stands still,
    until the play is taken up. 'dead_zone' is a hard play; 'elastic_contact' spreads the
    clearance over several compliant contact points, so the encoder is picked up gradually."""

    NAME = "backlash"
    ACTS_ON = (Stage.ANGLE,)
    FORMULATIONS = ("dead_zone", "elastic_contact")
    ORDER = 0   # mechanical: before any readout error
    SPECS = (
        ParamSpec("play_rad", "rad", "joint", 1e-3, 1.2e-2, valid=(0.0, 0.2),
                  doc="total lost motion: the travel between the two flanks"),
        ParamSpec("softness", "1", "joint", 0.3, 0.9, primary=False, valid=(0.0, 0.99),
                  formulations=("elastic_contact",),
                  doc="spread of the contact clearances, as a fraction of the mean half-play"),
    )

    def radii(self) -> np.ndarray:
        half = self.p("play_rad") / 2
        if self.formulation == "dead_zone":
            return half[None, :]
        spread = np.linspace(-1.0, 1.0, CONTACTS)[:, None] * self.p("softness")[None, :]
        return half[None, :] * (1.0 + spread)

    def encoder(self, angle, sig):
        return play(angle[:, None, :], self.radii()).mean(axis=1)

    def summary(self):
        return {"play_rad": self.p("play_rad"),
                # input travel after a reversal during which the encoder does not move at all
                "dwell_rad": 2 * self.radii().min(axis=0)}
