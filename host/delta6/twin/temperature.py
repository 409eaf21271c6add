"""The air temperature around the rig: heater set-points changed in steps, which the air
follows with a first-order lag (the paper's thermal test stepped from 15 to 40 degC with two
space heaters). Recorded in the log's ``temp_c`` by a thermometer next to the device."""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from delta6.core.operators import first_order
from delta6.twin.effects.base import grid_step
from delta6.twin.fields import number

ABSOLUTE_ZERO_C = -273.15
#: At most this many set-point changes: each is an array element drawn up front.
MAX_STEPS = 100_000


@dataclass(frozen=True)
class TemperatureSettings:
    low_c: float = 15.0
    high_c: float = 40.0
    start_c: float = 23.0
    steps: int = 5                 # set-point changes over the run
    sensor_noise_c: float = 0.05   # thermometer noise (standard deviation)

    def check(self) -> None:
        """A :class:`~delta6.twin.fields.FieldError` naming the first unusable setting."""
        number("low_c", self.low_c, ABSOLUTE_ZERO_C)
        number("high_c", self.high_c, self.low_c, low_is="low_c")
        number("start_c", self.start_c, ABSOLUTE_ZERO_C)
        number("steps", self.steps, 1, MAX_STEPS, integer=True)
        number("sensor_noise_c", self.sensor_noise_c, 0.0)

    def as_dict(self) -> dict:
        return asdict(self)


def ambient(t: np.ndarray, duration_s: float, rng: np.random.Generator,
            settings: TemperatureSettings = TemperatureSettings()) -> np.ndarray:
    """Air temperature (degC) at the fine times ``t``; steady at ``start_c`` before t = 0."""
    settings.check()
    step = max(duration_s, 1e-9) / settings.steps
    setpoints = np.concatenate([[settings.start_c],
                                rng.uniform(settings.low_c, settings.high_c, settings.steps)])
    index = np.where(t < 0, 0, np.minimum(np.floor(np.maximum(t, 0) / step).astype(int) + 1,
                                          settings.steps))
    target = setpoints[index]
    a = math.exp(-grid_step(t) / (step / 4))   # the air settles within a step
    return first_order(target, a, settings.start_c)
