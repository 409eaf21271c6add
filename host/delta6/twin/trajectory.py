"""The joint motion the calibration robot imposes (the true joint deflections).

The paper's rig moved the Delta6 against the reference sensor along a random trajectory
covering most of the workspace, and its durability test issued a new sampled Cartesian command
every 4 s. :class:`RandomTrajectory` does the same in joint space: point-to-point moves to
random waypoints in the joint box, each a minimum-jerk profile (what a robot's trajectory
generator produces) of random duration (so the speeds vary with distance and duration), an
optional hold, plus a small smooth dither
whose envelope comes and goes (small reversals at varied amplitudes: minor hysteresis loops).
Every joint reverses at about half of the waypoints and many more times with the dither.

A path is anything with ``evaluate(t) -> (q, qd)``, angles (M, 6) rad and rates rad/s;
:class:`FunctionPath` wraps a function for tests and custom experiments.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np

from delta6.twin.fields import number

# Minimum-jerk profile s(u) = 10u^3 - 15u^4 + 6u^5: peak rate 1.875/T, peak acceleration
# 5.7735/T^2 for a unit move of duration T.
_PEAK_RATE = 1.875
_PEAK_ACCEL = 10.0 / math.sqrt(3.0)
#: The dither takes at most this share of the covered joint range (the waypoints the rest).
MAX_DITHER_SHARE = 0.25


@dataclass(frozen=True)
class TrajectorySettings:
    """Knobs of the random trajectory (recorded in the truth file)."""

    coverage: float = 0.9                 # waypoints within +-coverage * joint limit
    move_min_s: float = 1.0               # duration of a move, log-uniform in range (a new
    move_max_s: float = 8.0               # command every ~4 s with the holds, as in the paper)
    speed_max_rad_s: float = 1.0          # moves are slowed down to respect both limits
    accel_max_rad_s2: float = 4.0
    hold_probability: float = 0.25        # a hold after a move
    hold_max_s: float = 2.0
    dither_rad: float = 0.02              # peak dither per joint (sum of three sinusoids;
                                          # less in a narrow box: MAX_DITHER_SHARE)
    dither_min_hz: float = 0.15
    dither_max_hz: float = 1.2
    scale: float = 1.0                    # multiplies the whole path (load level)

    def check(self) -> None:
        """A :class:`~delta6.twin.fields.FieldError` naming the first unusable setting."""
        number("coverage", self.coverage, 0.0, 1.0, above=True)
        number("move_min_s", self.move_min_s, 0.0, above=True)
        number("move_max_s", self.move_max_s, self.move_min_s, low_is="move_min_s")
        number("speed_max_rad_s", self.speed_max_rad_s, 0.0, above=True)
        number("accel_max_rad_s2", self.accel_max_rad_s2, 0.0, above=True)
        number("hold_probability", self.hold_probability, 0.0, 1.0)
        number("hold_max_s", self.hold_max_s, 0.0)
        number("dither_rad", self.dither_rad, 0.0)
        number("dither_min_hz", self.dither_min_hz, 0.0, above=True)
        number("dither_max_hz", self.dither_max_hz, self.dither_min_hz, low_is="dither_min_hz")
        number("scale", self.scale, 0.0, 1.0, above=True)

    def as_dict(self) -> dict:
        return asdict(self)


def quintic_moves(t: np.ndarray, starts: np.ndarray, durations: np.ndarray,
                  origins: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose and rate at times ``t`` of a path of moves, each from ``origins[i]`` to
    ``targets[i]`` over ``durations[i]`` from ``starts[i]`` along a quintic (zero speed and
    acceleration at both ends), holding the target after it; at rest (0) before t = 0 (the rig
    starts unloaded)."""
    idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)
    length = durations[idx]
    u = np.clip((t - starts[idx]) / length, 0.0, 1.0)
    shape = u**3 * (10 - 15 * u + 6 * u**2)
    rate = 30 * u**2 * (1 - u) ** 2 / length
    delta = targets[idx] - origins[idx]
    q = origins[idx] + delta * shape[:, None]
    qd = delta * rate[:, None]
    rest = t[:, None] < 0
    return np.where(rest, 0.0, q), np.where(rest, 0.0, qd)


class RandomTrajectory:
    """Random point-to-point moves with dither over [0, duration_s] (and at rest before 0)."""

    def __init__(self, joint_limit_rad: float, duration_s: float, rng: np.random.Generator,
                 settings: TrajectorySettings = TrajectorySettings()):
        settings.check()
        self.settings = s = settings
        covered = s.coverage * joint_limit_rad
        # The dither shrinks with a narrow box (every valid design's box, down to
        # MIN_JOINT_LIMIT_RAD, leaves the waypoints room); the default box keeps dither_rad.
        self.dither_rad = min(s.dither_rad, MAX_DITHER_SHARE * covered)
        reach = covered - self.dither_rad
        if reach <= 0:
            raise ValueError("the joint box is empty")
        starts, durations, origins, targets = [], [], [], []
        now, here = 0.0, np.zeros(6)
        while now < duration_s:
            target = rng.uniform(-reach, reach, 6)
            distance = float(np.abs(target - here).max())
            length = math.exp(rng.uniform(math.log(s.move_min_s), math.log(s.move_max_s)))
            length = max(length, _PEAK_RATE * distance / s.speed_max_rad_s,
                         math.sqrt(_PEAK_ACCEL * distance / s.accel_max_rad_s2))
            starts.append(now), durations.append(length), origins.append(here), targets.append(target)
            now += length
            here = target
            if rng.uniform() < s.hold_probability:
                hold = rng.uniform(0.0, s.hold_max_s)
                starts.append(now), durations.append(max(hold, 1e-3))
                origins.append(here), targets.append(here)
                now += hold
        self.starts = np.array(starts)
        self.durations = np.array(durations)
        self.origins = np.array(origins)
        self.targets = np.array(targets)
        # Dither: three sinusoids per joint, amplitudes summing to dither_rad, under an envelope
        # sin^2 of a slow sinusoid, so that it comes and goes.
        self.freq = rng.uniform(s.dither_min_hz, s.dither_max_hz, (3, 6))
        self.phase = rng.uniform(0, 2 * np.pi, (3, 6))
        share = rng.dirichlet(np.ones(3), 6).T
        self.amp = self.dither_rad * share
        self.env_freq = rng.uniform(0.01, 0.05, 6)

    @property
    def moves(self) -> int:
        return int(np.count_nonzero(np.any(self.origins != self.targets, axis=1)))

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        q, qd = quintic_moves(t, self.starts, self.durations, self.origins, self.targets)
        dq, dqd = self._dither(np.maximum(t, 0.0))
        scale = self.settings.scale
        return scale * (q + dq), scale * (qd + dqd)

    def _dither(self, t):
        w = 2 * np.pi * self.freq                                   # (3, 6)
        arg = w[None] * t[:, None, None] + self.phase[None]         # (M, 3, 6)
        wave = (self.amp[None] * np.sin(arg)).sum(axis=1)
        dwave = (self.amp[None] * w[None] * np.cos(arg)).sum(axis=1)
        # Envelope sin^2(pi f t): zero at t = 0, so that the path starts at rest.
        arg_env = np.pi * self.env_freq[None] * t[:, None]
        env = np.sin(arg_env) ** 2
        denv = np.pi * self.env_freq[None] * np.sin(2 * arg_env)
        return env * wave, env * dwave + denv * wave


class FunctionPath:
    """A path given by a function of time returning (q, qd), each (M, 6)."""

    def __init__(self, fn: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                 description: str = "custom path"):
        self.fn = fn
        self.description = description

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q, qd = self.fn(np.asarray(t, dtype=float))
        return np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
