"""One simulated calibration run: the robot moves the Delta6 against the reference sensor.

The robot imposes the true joint deflections (``trajectory``); the true plant (``plant``, with
the active effects) turns them into the true wrench and into what the encoders see; the rig
records what a real one would (``measurement``): 14-bit encoder angles, the reference wrench
with noise mapped to {E} by eq. (14), and the air temperature when asked. The analytical model
applied to the logged angles then shows the sim-to-real gap.

Random streams are keyed by the seed and a name (``twin.streams``): adding or removing an
effect changes nothing else of a run.
"""
from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from delta6.core import accuracy, model
from delta6.core.design import Design
from delta6.core.spec import full_scale
from delta6.twin import plant
from delta6.twin.effects import Effect, Signals, Stage
from delta6.twin.measurement import Measurement
from delta6.twin.streams import stream
from delta6.twin.temperature import TemperatureSettings, ambient
from delta6.twin.trajectory import RandomTrajectory, TrajectorySettings
from delta6.twin.truth import build_truth

#: Seconds at rest simulated before t = 0 (the lags and the latency start settled).
PRE_ROLL_S = 1.0
MAX_SAMPLES = 20_000_000

Progress = Callable[[str, float], None]


@dataclass
class SimResult:
    """A simulated run: the logged arrays, the hidden ground truth, and the truth record."""

    design: Design
    t: np.ndarray                 # (N,) s
    theta: np.ndarray             # (N, 6) encoder angles as logged, rad
    wrench: np.ndarray            # (N, 6) reference wrench in {E} as logged, N / N*m
    temp_c: np.ndarray | None     # (N,) logged temperature, when recorded
    true_angles: np.ndarray       # (N, 6) true joint deflections (not in the log)
    true_wrench: np.ndarray       # (N, 6) plant wrench, before latency and noise (not logged)
    truth: dict = field(default_factory=dict)
    path: object = None           # the joint path the robot followed (evaluate(t) -> q, qd)

    def __len__(self) -> int:
        return len(self.t)

    def model_wrench(self) -> np.ndarray:
        """The analytical model applied to the logged angles (computed once, read-only)."""
        return self._model_wrench

    @functools.cached_property
    def _model_wrench(self) -> np.ndarray:
        w = model.wrench(self.design, self.theta)
        w.flags.writeable = False   # shared by every caller
        return w

    def gap(self, which=accuracy.PERCENTILES) -> dict[str, list[float]]:
        """The analytical model's per-axis error against the reference, % FS percentiles."""
        return accuracy.percentiles(self.model_wrench(), self.wrench, full_scale(self.design),
                                    which)


def simulate(design: Design, effects: Sequence[Effect] = (), duration_s: float = 2000.0,
             rate_hz: float = 50.0, seed: int = 0, *, path=None,
             trajectory: TrajectorySettings = TrajectorySettings(),
             temperature: TemperatureSettings = TemperatureSettings(),
             measurement: Measurement = Measurement(), record_temp: bool | None = None,
             oversample: int = 4, scenario: str | None = None,
             progress: Progress | None = None) -> SimResult:
    """Simulate a calibration run (see the module docstring and docs/twin.md).

    ``effects``: configured effects (``twin.make_effect``, ``twin.scenario_effects``), at most
    one per name. ``path``: a custom joint path (``evaluate(t) -> (q, qd)``) instead of the
    random trajectory. ``record_temp``: write ``temp_c`` (default: when thermal_drift is active;
    pass True to have the column whatever the effects, so its presence reveals nothing).
    ``oversample``: plant steps per logged sample (history effects see the motion between
    samples). ``progress(stage, fraction)`` is called as the run advances.
    """
    started = time.perf_counter()
    _check(effects, duration_s, rate_hz, seed, oversample)
    measurement.check()
    say = progress or (lambda stage, fraction: None)
    n_log = int(round(duration_s * rate_hz))
    n_pre = int(np.ceil(PRE_ROLL_S * rate_hz)) * oversample
    dt = 1.0 / (rate_hz * oversample)
    fine_t = (np.arange(n_pre + n_log * oversample) - n_pre) * dt
    logged = n_pre + oversample * np.arange(n_log)

    say("trajectory", 0.0)
    if path is None:
        path = RandomTrajectory(design.joint_limit_rad, duration_s, stream(seed, "trajectory"),
                                trajectory)
    q, qd = path.evaluate(fine_t)
    temp = ambient(fine_t, duration_s, stream(seed, "temperature"), temperature)
    nominal = model.Params.from_design(design)
    sig = Signals(t=fine_t, q=q, qd=qd, temp_c=temp, nominal=nominal)
    say("trajectory", 1.0)

    out = plant.run(effects, sig, logged, progress=lambda f: say("plant", f))

    say("measurement", 0.0)
    theta = measurement.encoders(out.encoder[logged])
    wrench = measurement.reference(out.reference, stream(seed, "reference noise"))
    if record_temp is None:
        record_temp = any(e.NAME == "thermal_drift" for e in effects)
    temp_c = None
    if record_temp:
        noise = stream(seed, "thermometer").standard_normal(n_log) * temperature.sensor_noise_c
        temp_c = temp[logged] + noise
    say("measurement", 1.0)

    result = SimResult(design=design, t=fine_t[logged], theta=theta, wrench=wrench,
                       temp_c=temp_c, true_angles=q[logged], true_wrench=out.wrench,
                       path=path)
    result.truth = build_truth(
        result, effects=effects, seed=seed, duration_s=duration_s, rate_hz=rate_hz,
        oversample=oversample, scenario=scenario,
        trajectory=trajectory.as_dict() if isinstance(path, RandomTrajectory)
        else {"custom": getattr(path, "description", type(path).__name__)},
        temperature=temperature, measurement=measurement,
        seconds=time.perf_counter() - started)
    return result


def _check(effects, duration_s, rate_hz, seed, oversample) -> None:
    if not (isinstance(seed, (int, np.integer)) and seed >= 0):
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate must be a positive number of Hz, got {rate_hz!r}")
    if not (np.isfinite(duration_s) and duration_s * rate_hz >= 2):
        raise ValueError(f"duration {duration_s!r} s gives fewer than 2 samples at {rate_hz:g} Hz")
    plant.check_oversample(oversample)
    if duration_s * rate_hz * oversample > MAX_SAMPLES:
        raise ValueError(f"{duration_s:g} s at {rate_hz:g} Hz is more than this simulator "
                         f"holds in memory ({MAX_SAMPLES} plant steps)")
    names = [e.NAME for e in effects]
    if len(set(names)) != len(names):
        raise ValueError("each effect may appear once: " + ", ".join(names))
    for e in effects:
        if not isinstance(e, Effect) or not e.ACTS_ON or not all(isinstance(s, Stage)
                                                                  for s in e.ACTS_ON):
            raise ValueError(f"not a configured effect: {e!r}")
