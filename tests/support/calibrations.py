"""Calibrations for tests: random ones for the cross-checks of the calibrated model (native
and AVR), and a fixed one with history terms for the learned residuals over a calibration."""
from __future__ import annotations

import dataclasses

import numpy as np

from delta6.core import calibration as C


def random_calibration(design, seed: int, scale: float = 1.0) -> C.Calibration:
    """Everything a unit can have, drawn around the realistic ranges (scale 1)."""
    rng = np.random.default_rng(seed)

    def u(hi, shape, signed=True):
        return rng.uniform(-hi if signed else 0.0, hi, shape) * scale

    radii = tuple(sorted(rng.choice([8, 16, 32, 64, 128, 256, 512], rng.integers(1, 5),
                                    replace=False).tolist()))
    speeds = tuple(sorted(rng.uniform(0.002, 0.05, rng.integers(1, 5)).tolist()))
    return C.neutral(design, f"random-{seed % 1000}").with_(
        offset_rad=u(0.015, 6), backlash_play_rad=u(0.012, 6, False),
        direction_half_counts=int(rng.integers(1, 8)), rate_ratio=1.0 + u(0.12, 6),
        hysteresis_radii_counts=radii, hysteresis_nm=u(0.01, (6, len(radii))),
        speed_filter_s=float(rng.uniform(0.005, 0.1)), friction_speeds_rad_s=speeds,
        friction_sign_nm=u(0.008, (6, len(speeds))), viscous_nm_s_per_rad=u(0.005, 6),
        presliding_nm=u(0.003, 6), delta_a_mm=u(0.5, 3), delta_b_mm=u(0.5, 3),
        delta_la_mm=u(0.5, 3), delta_lb_mm=u(1.0, 3), delta_azimuth_rad=u(0.01, 3),
        delta_rest_angle_rad=u(0.01, 3), gimbal_misalignment_rad=u(0.01, 3),
        elbow_rad_per_nm=u(0.1, 3, False), tilt_rad_per_nm=float(u(0.08, (), False)),
        # The friction held beyond a speed on most joints (0: no limit), within the speeds
        # the cross-checks' walks reach.
        friction_speed_limit_rad_s=np.where(rng.random(6) < 0.3, 0.0,
                                            rng.uniform(0.005, 0.5, 6)),
        # A led friction speed on most (a new calibration's 10 ms, or any up to 30 ms).
        speed_lead_s=float(rng.choice([0.0, C.DEFAULT_SPEED_LEAD_S, rng.uniform(0.0, 0.03)])))


def with_curves(cal: C.Calibration, seed: int, spring: bool = True,
                encoder: bool = True) -> C.Calibration:
    """``cal`` with per-joint curves of realistic size: a stiffening spring (curvature up to
    0.3 of the nominal torque at the reference) and a magnet's periodic error (up to 0.015 rad
    in the first harmonic, falling as 1/h, any phase)."""
    rng = np.random.default_rng(seed)
    effects = list(cal.effects)
    if spring:
        cal = cal.with_(spring_curvature=rng.uniform(-0.3, 0.3, (6, 2)))
        effects.append("nonlinear_spring")
    if encoder:
        harmonics = np.repeat(np.arange(1, 5), 2)
        cal = cal.with_(encoder_periodic_rad=rng.uniform(-0.015, 0.015, (6, 8)) / harmonics)
        effects.append("encoder_periodic_error")
    return cal.with_(effects=tuple(effects))


def history_calibration(design, name: str, viscous_nm_s_per_rad: float = 0.0) -> C.Calibration:
    """A calibration with history terms (hysteresis plays, backlash; friction if
    ``viscous_nm_s_per_rad``), so that the base carries state from sample to sample."""
    neutral = C.neutral(design, name)
    hysteresis = np.zeros_like(neutral.hysteresis_nm)
    hysteresis[:, 0] = 0.002
    return dataclasses.replace(
        neutral, effects=("stiffness_mismatch", "spring_hysteresis", "backlash"),
        rate_ratio=np.array([1.05, 0.99, 1.08, 1.07, 0.93, 1.0]), hysteresis_nm=hysteresis,
        backlash_play_rad=np.full(6, 0.004),
        viscous_nm_s_per_rad=np.full(6, viscous_nm_s_per_rad))
