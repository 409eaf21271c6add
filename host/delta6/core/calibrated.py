"""The calibrated model: the analytical model with a unit's calibration applied, causally.

One implementation serves the host (``delta6 evaluate``, applying a calibration to streamed
raw counts), the tests and the firmware checks; the firmware's C++ version
(``firmware/lib/delta6_core/src/delta6_calibrated.cpp``) computes the same thing in float32
and is cross-checked against this one. Every term uses the present and past samples only,
through a few numbers of state per joint (:class:`ModelState`), in one pass per sample:

1. **history features** of each joint's count x (signed counts from the zero, as the board
   has them): the direction of motion ``d`` (a play of +-``direction_half_counts``/2 counts:
   +1 after rising, -1 after falling), hysteresis states ``h_r = (x - play_r(x)) / r`` for the
   play radii r (whole counts: the plays stay whole numbers, exactly, on both sides), and the
   joint speed ``v``, a first-order filtered difference (time constant ``speed_filter_s``);
   the step of a sample that follows lost ones (a failed read, a lost record: ``periods``
   over 1) spans more than a period and is no speed: the speed decays for that sample as if
   the joint stood still, as the board does after a failed read. The friction takes that
   speed led by ``speed_lead_s`` of its filtered acceleration (``led_speed``: the filtered
   speed lags the true one at the reversals, where the friction switches).
2. **angle side**: theta = x * count - offset - e(x) + backlash_play / 2 * d (the link leads
   its encoder by half the play in the direction of motion; e is the encoder's periodic
   error, tabulated over x: ``delta6.core.curves``).
3. **torque**: tau = k * rate_ratio * theta + s(x) + sum_r w_r h_r
   + sum_s c_s clamp(v / V_s, -1, 1) + viscous * v + presliding * d, with v held within
   +-``friction_speed_limit_rad_s`` where that is set (s: the spring's curve
   beyond its rate, tabulated over x; the encoder error's torque k * rate_ratio * e(x) comes
   from the same table as the board's, ``CurveTables.torque``).
4. **geometry**: each branch has its own a, b, la, lb, azimuth and rest angle; the elbow turns
   by ``elbow_rad_per_nm * tau_i`` (load-dependent compliance, kinematics only).
5. **statics** (eqs. 2-11) with those torques in that geometry, then the gimbal: the force
   turns by the small rotation w = gimbal_misalignment + tilt * (moment about the platform
   centre), F_E0 = F - w x F; eq. (12) with the corrected angles of joints 4..6.

The reference sensor's latency is not applied: it belongs to the calibration rig.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from delta6.core import curves, model
from delta6.core.calibration import Calibration
from delta6.core.design import Design
from delta6.core.model import ENCODER_COUNT_RAD, Params
from delta6.core.operators import affine_scan, play


@dataclass
class ModelState:
    """The history a calibrated model carries from one sample to the next, per joint:
    the direction play (half counts), the hysteresis plays (counts), the filtered speed
    (rad/s) and the last count. The board keeps the same numbers."""

    direction2: np.ndarray   # (6,)
    plays: np.ndarray        # (6, R)
    speed: np.ndarray        # (6,)
    last: np.ndarray         # (6,)
    lead: np.ndarray         # (6,) the speed's lead (rad/s): speed_lead_s x filtered acceleration

    @classmethod
    def settled(cls, counts0, radii_count: int) -> "ModelState":
        """At rest at ``counts0``: every play centred on it, no speed."""
        x = np.asarray(counts0, dtype=float)
        return cls(direction2=2.0 * x, plays=np.repeat(x[:, None], radii_count, axis=1),
                   speed=np.zeros(6), last=x.copy(), lead=np.zeros(6))


@dataclass
class JointTerms:
    theta: np.ndarray        # (n, 6) corrected joint angles, rad
    torque: np.ndarray       # (n, 6) joint torques, N*m
    direction: np.ndarray    # (n, 6) in [-1, 1]
    hysteresis: np.ndarray   # (n, 6, R) in [-1, 1]
    speed: np.ndarray        # (n, 6) rad/s, the friction's (led) speed


def counts_from_angles(theta: np.ndarray) -> np.ndarray:
    """Encoder angles (rad) as signed whole counts, what the board computes from."""
    return np.round(np.asarray(theta, dtype=float) / ENCODER_COUNT_RAD)


def sample_period(t: np.ndarray) -> float:
    """The sample period of a log (median step; logs are sampled uniformly up to jitter)."""
    t = np.asarray(t, dtype=float)
    return float(np.median(np.diff(t))) if len(t) > 1 else 0.0


def speed_filter(tau: float, dt: float) -> tuple[float, float]:
    """v_n = a v_(n-1) + g (x_n - x_(n-1)): backward-Euler low pass of the count difference
    (rad/s per count step). Returns (a, g)."""
    if dt <= 0:
        return 1.0, 0.0
    a = tau / (tau + dt)
    return a, (1.0 - a) * ENCODER_COUNT_RAD / dt


def speed_gains(tau: float, dt: float, periods: np.ndarray | None, n: int) -> np.ndarray:
    """Per sample, the g of v_n = a v_(n-1) + g (x_n - x_(n-1)): 0 after lost periods (the
    step spans more than one period: no speed)."""
    _, g = speed_filter(tau, dt)
    if periods is None:
        return np.full((n, 1), g)
    return np.where(np.asarray(periods).reshape(n, 1) > 1, 0.0, g)


def filtered_speed(counts: np.ndarray, dt: float, tau: float,
                   periods: np.ndarray | None = None, speed0=None, last=None) -> np.ndarray:
    """The board's joint speed (rad/s) of counts (n, j): the filtered count difference of
    :func:`speed_filter`, continuing from the speed ``speed0`` and the count ``last`` of the
    sample before (default: at rest at the first sample)."""
    x = np.asarray(counts, dtype=float)
    a, _ = speed_filter(tau, dt)
    g = speed_gains(tau, dt, periods, len(x))
    step = np.diff(x, axis=0, prepend=(x[:1] if last is None else np.reshape(last, (1, -1))))
    return affine_scan(np.full(x.shape, a), g * step,
                       np.zeros(x.shape[1]) if speed0 is None else speed0)


def lead_filter(tau: float, dt: float) -> tuple[float, float]:
    """w_n = a w_(n-1) + k (v_n - v_(n-1)): the speed's filtered acceleration (time constant
    twice the speed filter's, backward Euler as the speed's) per unit of lead, in rad/s per
    rad/s of speed change and second of lead. Returns (a, k)."""
    if dt <= 0:
        return 1.0, 0.0
    slow = 2.0 * tau
    a = slow / (slow + dt)
    return a, (1.0 - a) / dt


def led_speed(speed: np.ndarray, dt: float, tau: float, lead: float, before=None,
              lead0=None) -> tuple[np.ndarray, np.ndarray]:
    """(the friction's speed, its lead) for filtered speeds ``speed`` (n, j): the speed plus
    ``lead`` seconds of its filtered acceleration (:func:`lead_filter`), continuing from the
    speed ``before`` and the lead ``lead0`` of the sample before (default: at rest)."""
    v = np.asarray(speed, dtype=float)
    zero = np.zeros(v.shape[1])
    if lead == 0 or len(v) == 0:
        return v, np.zeros_like(v)
    a, k = lead_filter(tau, dt)
    change = np.diff(v, axis=0, prepend=np.reshape(zero if before is None else before, (1, -1)))
    w = affine_scan(np.full(v.shape, a), (lead * k) * change, zero if lead0 is None else lead0)
    return v + w, w


def friction_speed(speed: np.ndarray, limit) -> np.ndarray:
    """The speed the friction is evaluated at: ``speed`` (n, 6) held within +-``limit`` (6,)
    where the limit is set (> 0); beyond, the friction stays what it was at the limit."""
    limit = np.asarray(limit, dtype=float)
    bound = np.where(limit > 0, limit, np.inf)
    return np.clip(speed, -bound, bound)


#: A log that spends more than this share of its samples beyond the fastest joint speed its
#: calibration run reached is told so, per joint (a run of the same kind of motion passes
#: that speed in a few samples now and then: its fastest sample is a noisy figure).
BEYOND_CALIBRATED_SHARE = 0.01


def speeds_beyond_calibration(cal: Calibration, t: np.ndarray, theta: np.ndarray) -> list[str]:
    """Notes, one per joint, where a log's board speed was beyond the speed up to which
    ``cal``'s friction was fitted (its ``friction_speed_limit_rad_s``) on more than
    ``BEYOND_CALIBRATED_SHARE`` of its samples: there the calibrated model holds the friction
    it knew."""
    limit = np.asarray(cal.friction_speed_limit_rad_s, dtype=float)
    if len(t) < 2 or not np.any(limit > 0):
        return []
    dt = sample_period(t)
    v = filtered_speed(counts_from_angles(theta), dt, cal.speed_filter_s, periods_between(t, dt))
    speed = np.abs(led_speed(v, dt, cal.speed_filter_s, cal.speed_lead_s)[0])
    share = (speed > limit).mean(axis=0)
    return [f"note: joint {j + 1} turned faster than the {limit[j]:.3g} rad/s its calibration "
            f"run reached in {share[j]:.0%} of the log (up to {speed[:, j].max():.3g} rad/s): "
            "its friction is held at that speed there (calibrate on a run that reaches the "
            "speeds the sensor sees)"
            for j in range(6) if limit[j] > 0 and share[j] > BEYOND_CALIBRATED_SHARE]


def periods_between(t: np.ndarray, dt: float, before: float | None = None) -> np.ndarray:
    """Sample periods from each row to the one before (``before``: the time of the row before
    the first; default: the first row counts 1) of a log's times: more than 1 where rows are
    missing (failed reads left out, records lost on the link)."""
    t = np.asarray(t, dtype=float)
    if dt <= 0 or len(t) == 0:
        return np.ones(len(t))
    first = t[0] - dt if before is None else before
    return np.maximum(np.round(np.diff(t, prepend=first) / dt), 1.0)


class CalibratedModel:
    """The analytical model of ``design`` with ``calibration`` applied (see the module doc).

    Also an estimator for ``delta6.evaluation.tablev``: ``name`` and ``predict(log)``.
    """

    name = "calibrated"

    def __init__(self, design: Design, calibration: Calibration, saturate_curves: bool = False):
        """``saturate_curves``: hold a curve beyond the board's table at the table's range
        (a fit's iterates) instead of refusing it (``curves.CurveRangeError``)."""
        calibration.check_design(design)
        self.design = design
        self.cal = calibration
        c = calibration
        nominal = Params.from_design(design)
        mm = 1e-3
        self.params = nominal.with_(
            a=nominal.a + c.delta_a_mm * mm, b=nominal.b + c.delta_b_mm * mm,
            la=nominal.la + c.delta_la_mm * mm, lb=nominal.lb + c.delta_lb_mm * mm,
            phi=nominal.phi + c.delta_azimuth_rad,
            offset=nominal.offset + c.delta_rest_angle_rad)
        self.radii = np.asarray(c.hysteresis_radii_counts, dtype=float)
        self.curves = curves.curve_tables(design, c, saturate=saturate_curves)

    # -- the pieces ---------------------------------------------------------------------------

    def joint_terms(self, counts: np.ndarray, dt: float, state: ModelState | None = None,
                    periods: np.ndarray | None = None) -> tuple[JointTerms, ModelState]:
        """Steps 1-3 for samples ``counts`` (n, 6) taken every ``dt`` seconds; ``periods``
        (n,): sample periods since the sample before (default 1 each)."""
        c = self.cal
        x = np.asarray(counts, dtype=float)
        if x.ndim != 2 or x.shape[1] != 6:
            raise ValueError(f"counts must have shape (n, 6), got {x.shape}")
        if state is None:
            state = ModelState.settled(x[0], len(self.radii))
        half = float(c.direction_half_counts)
        y2 = play(2.0 * x, half, state.direction2)
        direction = (2.0 * x - y2) / half
        yr = play(x[:, :, None], self.radii, state.plays)
        hysteresis = (x[:, :, None] - yr) / self.radii
        filtered = filtered_speed(x, dt, c.speed_filter_s, periods, state.speed, state.last)
        speed, lead = led_speed(filtered, dt, c.speed_filter_s, c.speed_lead_s, state.speed,
                                state.lead)
        theta = x * ENCODER_COUNT_RAD - c.offset_rad + 0.5 * c.backlash_play_rad * direction
        # The friction is known up to the speeds its calibration run reached, and held there
        # beyond (a viscous slope fitted on slow motion does not extrapolate).
        held = friction_speed(speed, c.friction_speed_limit_rad_s)
        signs = sum(c.friction_sign_nm[:, s] * np.clip(held / v, -1.0, 1.0)
                    for s, v in enumerate(c.friction_speeds_rad_s))
        torque = (self.design.k * c.rate_ratio * theta
                  + np.einsum("njr,jr->nj", hysteresis, c.hysteresis_nm)
                  + signs + c.viscous_nm_s_per_rad * held + c.presliding_nm * direction)
        tables = self.curves
        if tables is not None:
            # The board's tables: the torque table holds s - k ratio e, so theta's e is
            # subtracted after the torque is formed.
            torque = torque + curves.interpolate(tables.torque, tables.knots, x) \
                * 2.0 ** -curves.TORQUE_SHIFT
            if tables.angle is not None:
                theta = theta - curves.interpolate(tables.angle, tables.knots, x) \
                    * 2.0 ** -curves.ANGLE_SHIFT
        after = ModelState(direction2=y2[-1].copy(), plays=yr[-1].copy(),
                           speed=filtered[-1].copy(), last=x[-1].copy(), lead=lead[-1].copy())
        return JointTerms(theta, torque, direction, hysteresis, speed), after

    def wrench_from_terms(self, theta: np.ndarray, torque: np.ndarray) -> np.ndarray:
        """Steps 4-5: the wrench at {E} (n, 6) from corrected angles and joint torques."""
        c = self.cal
        p = self.params
        if np.any(c.elbow_rad_per_nm):
            p = p.with_(offset=p.offset + c.elbow_rad_per_nm * torque[:, :3])
        f_b = model.base_force(p, theta[:, :3], torque[:, :3])
        moment = torque[:, 3:]
        turn = c.gimbal_misalignment_rad + c.tilt_rad_per_nm * (
            moment + np.cross([0.0, 0.0, p.c], f_b))
        f_e0 = f_b - np.cross(turn, f_b)
        return model.wrench_in_e(theta[:, 3:], f_e0, moment)

    # -- whole runs ---------------------------------------------------------------------------

    def run(self, counts: np.ndarray, dt: float, state: ModelState | None = None,
            periods: np.ndarray | None = None) -> tuple[np.ndarray, ModelState]:
        """The wrench (n, 6) for samples ``counts`` (n, 6, signed counts from the zero) taken
        every ``dt`` s, continuing from ``state`` (default: settled at the first sample);
        returns the state after the last sample too, so a stream can be fed in pieces.
        ``periods`` (n,): sample periods since the sample before (default 1 each)."""
        terms, after = self.joint_terms(counts, dt, state, periods)
        return self.wrench_from_terms(terms.theta, terms.torque), after

    def predict(self, log) -> np.ndarray:
        """The calibrated wrench for a log's encoder angles (estimator protocol)."""
        dt = sample_period(log.t)
        wrench, _ = self.run(counts_from_angles(log.theta), dt,
                             periods=periods_between(log.t, dt))
        return wrench
