"""Helpers shared by the digital-twin tests: clean measurement, simple joint paths."""
from __future__ import annotations

import numpy as np

from delta6 import twin

#: No noise and no quantization: isolates the effect under test.
CLEAN = twin.Measurement(force_noise_n=0.0, moment_noise_nm=0.0, quantize=False)


def sine_path(joint: int, amplitude: float, freq_hz: float, base=0.0) -> twin.FunctionPath:
    """Joint ``joint`` (1-based) swings as amplitude*sin(2 pi f t) around ``base`` (other
    joints held at ``base``); at rest before t = 0."""
    base = np.broadcast_to(np.asarray(base, dtype=float), (6,))

    def fn(t):
        w = 2 * np.pi * freq_hz
        on = t >= 0
        q = np.tile(base, (len(t), 1))
        qd = np.zeros((len(t), 6))
        q[:, joint - 1] += np.where(on, amplitude * np.sin(w * t), 0.0)
        qd[:, joint - 1] = np.where(on, amplitude * w * np.cos(w * t), 0.0)
        return q, qd

    return twin.FunctionPath(fn, f"sine on joint {joint}")


def held_path(pose) -> twin.FunctionPath:
    """The joints held still at ``pose`` (6,) for the whole run."""
    pose = np.asarray(pose, dtype=float)
    return twin.FunctionPath(lambda t: (np.tile(pose, (len(t), 1)), np.zeros((len(t), 6))),
                             "held pose")


def reversed_path(path, duration_s: float) -> twin.FunctionPath:
    """The same poses visited backwards in time (history reversed, poses unchanged)."""
    def fn(t):
        q, qd = path.evaluate(np.clip(duration_s - t, 0.0, None))
        return q, -qd
    return twin.FunctionPath(fn, "reversed path")


def residual(result) -> np.ndarray:
    """The analytical model's error against the reference, (N, 6)."""
    return result.model_wrench() - result.wrench


def twin_log(design, effects, seed: int, duration_s: float = 240.0):
    """A twin run as the log `delta6 diagnose` reads (50 Hz, temperature recorded)."""
    from delta6.link.logfile import LogData
    r = twin.simulate(design, effects, duration_s=duration_s, rate_hz=50.0, seed=seed,
                      record_temp=True)
    return LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c)


def lugre_friction_log(design):
    """A LuGre friction alone, whose verdict names a hysteresis it trades with only in the
    group (tests/diagnosis/test_naming_rules.py; its calibration, tests/calibration)."""
    friction = twin.make_effect("joint_friction", seed=41, formulation="lugre", magnitude=0.9)
    return twin_log(design, [friction], 41)
