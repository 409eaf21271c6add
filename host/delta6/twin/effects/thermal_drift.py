"""``thermal_drift``: spring rates and encoder zeros change with temperature (torque and
angle side; the log then carries ``temp_c``)."""
from __future__ import annotations

import numpy as np

from delta6.twin.effects.base import Effect, ParamSpec, Stage


class ThermalDrift(Effect):
    """The modulus of spring steel falls by about 0.025 %/degC and the PLA clips that preload the
    antagonistic pairs expand and soften, so the joint rates fall as the room warms; the
    magnet holders expand too and the encoder zeros creep. 'instant' follows the logged
    temperature; 'lagged' lets the springs and magnets follow it through a first-order thermal
    time constant (the device heats more slowly than the air next to it)."""

    NAME = "thermal_drift"
    ACTS_ON = (Stage.TORQUE, Stage.ANGLE)
    FORMULATIONS = ("instant", "lagged")
    ORDER = 20   # a readout drift, after the play and the fixed offset
    SPECS = (
        ParamSpec("stiffness_coeff_per_c", "1/degC", "joint", 1e-4, 1.5e-3, sign="-",
                  valid=(-0.01, 0.01), doc="relative change of the spring rate per degC"),
        ParamSpec("offset_coeff_rad_per_c", "rad/degC", "joint", 2e-5, 3e-4, sign="+-",
                  valid=(-0.01, 0.01), doc="encoder zero drift per degC"),
        ParamSpec("ref_temp_c", "degC", "scalar", 23.0, 23.0, primary=False,
                  valid=(-40.0, 120.0), doc="temperature at which the device was zeroed and k "
                                            "calibrated"),
        ParamSpec("lag_s", "s", "scalar", 20.0, 300.0, primary=False, valid=(0.0, 1e5),
                  formulations=("lagged",), doc="thermal time constant of the device"),
    )

    def _rise(self, sig) -> np.ndarray:
        """Device temperature above the reference, (M, 1)."""
        temp = sig.temp_c
        if self.formulation == "lagged":
            temp = sig.lagged_temp(float(self.p("lag_s")))
        return (temp - float(self.p("ref_temp_c")))[:, None]

    def spring_scale(self, sig):
        return 1.0 + self.p("stiffness_coeff_per_c") * self._rise(sig)

    def encoder(self, angle, sig):
        return angle + self.p("offset_coeff_rad_per_c") * self._rise(sig)

    def summary(self):
        return {
            "stiffness_coeff_per_c": self.p("stiffness_coeff_per_c"),
            "offset_coeff_rad_per_c": self.p("offset_coeff_rad_per_c"),
            "ref_temp_c": float(self.p("ref_temp_c")),
            "lag_s": float(self.p("lag_s")) if self.formulation == "lagged" else 0.0,
        }
