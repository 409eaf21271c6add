"""A log prepared for diagnosis: validated arrays, the model's prediction, the residual and the
per-sample sensitivity maps, computed once and shared by every candidate effect."""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from delta6.core.design import Design
from delta6.core.errors import UserError
from delta6.core.model import AXES, Params, forward_kinematics, wrench
from delta6.core.spec import full_scale
from delta6.diagnosis import sensitivity
from delta6.link.logfile import LogData

#: Temperature at which the design's spring rates and the encoder zeros are taken to hold.
DEFAULT_REF_TEMP_C = 23.0
#: A reference wrench beyond this many full scales of the design on any axis is no load the
#: mechanism can have carried inside its joint box: a corrupt row, a unit error, another design.
MAX_FULL_SCALES = 3.0
#: Below this many samples the held-out scoring has too few independent blocks to mean much.
MIN_SAMPLES = 2000


class DiagnosisInputError(UserError):
    """The log cannot be diagnosed; the message names the problem."""


@dataclass
class GapData:
    design: Design
    params: Params
    t: np.ndarray            # (n,) s
    theta: np.ndarray        # (n, 6) encoder angles, rad
    reference: np.ndarray    # (n, 6) reference wrench in {E}
    temp_c: np.ndarray | None
    fs: np.ndarray           # (6,) full scale, N and N*m
    ref_temp_c: float = DEFAULT_REF_TEMP_C  # temperature at which k and zeros were set

    @classmethod
    def from_log(cls, log: LogData, design: Design,
                 ref_temp_c: float = DEFAULT_REF_TEMP_C) -> "GapData":
        n = len(log.t)
        if n < MIN_SAMPLES:
            raise DiagnosisInputError(f"too few samples: {n} (the diagnosis needs at least "
                                      f"{MIN_SAMPLES} for time-blocked held-out scoring)")
        for name, values in (("t", log.t), ("theta_e", log.theta), ("wrench", log.wrench)):
            if not np.all(np.isfinite(values)):
                raise DiagnosisInputError(f"NaN or infinite {name} values in the log")
        if np.any(np.diff(log.t) <= 0):
            raise DiagnosisInputError("time is not strictly increasing")
        temp = log.temp_c
        if temp is not None and not np.all(np.isfinite(temp)):
            raise DiagnosisInputError("NaN or infinite temp_c values in the log")
        fs = full_scale(design)
        over = np.abs(log.wrench) > MAX_FULL_SCALES * fs
        if over.any():
            row, axis = (int(v) for v in np.argwhere(over)[0])
            unit = "N" if axis < 3 else "N*m"
            raise DiagnosisInputError(
                f"{int(over.any(axis=1).sum())} samples have a reference wrench far outside "
                f"the design's range, the first at t = {log.t[row]:g} s: {AXES[axis]} = "
                f"{log.wrench[row, axis]:.4g} {unit} (full scale {fs[axis]:.4g} {unit}; up to "
                f"{MAX_FULL_SCALES:g}x is accepted): a corrupt log, a unit error or the wrong "
                "design")
        limit = design.joint_limit_rad
        outside = np.abs(log.theta) > 1.5 * limit
        if outside.mean() > 0.01:
            raise DiagnosisInputError(
                f"{outside.any(axis=1).mean():.0%} of the samples have encoder angles far "
                f"outside the joint box (|theta_e| > {1.5 * limit:.2f} rad): wrong units "
                "(degrees?) or wrong design")
        data = cls(design=design, params=Params.from_design(design), t=np.asarray(log.t, float),
                   theta=np.asarray(log.theta, float), reference=np.asarray(log.wrench, float),
                   temp_c=None if temp is None else np.asarray(temp, float),
                   fs=fs, ref_temp_c=ref_temp_c)
        if not np.all(np.isfinite(data.model)):
            raise DiagnosisInputError("the analytical model has no solution for some logged "
                                      "angles: wrong design for this log?")
        return data

    def __len__(self) -> int:
        return len(self.t)

    @functools.cached_property
    def model(self) -> np.ndarray:
        return wrench(self.params, self.theta)

    @functools.cached_property
    def residual(self) -> np.ndarray:
        """Reference minus model: what the analytical model misses."""
        return self.reference - self.model

    @functools.cached_property
    def residual_pct(self) -> np.ndarray:
        return 100.0 * self.residual / self.fs

    @functools.cached_property
    def velocity(self) -> np.ndarray:
        """Encoder angular velocity, rad/s (central differences)."""
        return np.gradient(self.theta, self.t, axis=0)

    @functools.cached_property
    def position_mm(self) -> np.ndarray:
        return forward_kinematics(self.params, self.theta[:, :3]) * 1e3

    @functools.cached_property
    def torque_map(self) -> np.ndarray:
        return sensitivity.torque_map(self.params, self.theta)

    @functools.cached_property
    def angle_jacobian(self) -> np.ndarray:
        return sensitivity.angle_jacobian(self.params, self.theta)

    @functools.cached_property
    def geometry_jacobian(self) -> np.ndarray:
        return sensitivity.geometry_jacobian(self.params, self.theta)

    @functools.cached_property
    def residual_joint_torque(self) -> np.ndarray:
        """The residual expressed as the extra joint torques that would explain it,
        G^-1 r (N*m): makes torque-side effects (hysteresis, friction) visible per joint."""
        return np.linalg.solve(self.torque_map, self.residual[..., None])[..., 0]
