"""``sensor_latency``: the reference wrench lags the encoder samples (time)."""
from __future__ import annotations

import numpy as np

from delta6.core.operators import first_order
from delta6.twin.effects.base import Effect, ParamSpec, Stage


class SensorLatency(Effect):
    """The reference sensor and the Delta6 are sampled by different boxes (the F/T sensor's DAQ
    with its own filter and USB link, the Delta6 polled over serial) and paired by host arrival
    time: the wrench in a log row is older than the angles by a few to a few tens of
    milliseconds. 'delay' is a pure transport delay; 'first_order' is the DAQ's low-pass
    filter, whose low-frequency group delay is its time constant."""

    NAME = "sensor_latency"
    ACTS_ON = (Stage.TIME,)
    FORMULATIONS = ("delay", "first_order")
    PER_JOINT = False
    SPECS = (
        ParamSpec("latency_s", "s", "scalar", 0.002, 0.04, valid=(0.0, 1.0),
                  doc="transport delay, or the filter time constant (its group delay at low "
                      "frequency)"),
    )

    def reference(self, wrench, sig):
        latency = float(self.p("latency_s"))
        if self.formulation == "delay":
            back = sig.t - latency
            return np.stack([np.interp(back, sig.t, w) for w in wrench.T], axis=1)
        # Backward Euler, a = tau / (tau + dt): its DC group delay is tau.
        return first_order(wrench, latency / (latency + sig.dt))

    def summary(self):
        return {"latency_s": float(self.p("latency_s"))}
