"""A log prepared for diagnosis: validated arrays, the model's prediction, the residual and the
per-sample sensitivity maps, computed once and shared by every candidate effect."""
from __future__ import annotations

import contextlib
import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

from delta6.core.calibrated import filtered_speed, led_speed, periods_between
from delta6.core.calibration import DEFAULT_SPEED_FILTER_S, DEFAULT_SPEED_LEAD_S
from delta6.core.design import Design
from delta6.core.errors import UserError
from delta6.core.model import AXES, ENCODER_COUNT_RAD, Params, forward_kinematics, wrench
from delta6.core.spec import full_scale
from delta6.diagnosis import sensitivity
from delta6.diagnosis.signals import dwell_ramps, lagged, play_output, smooth_velocity
from delta6.link.logfile import LogData

#: Temperature at which the design's spring rates and the encoder zeros are taken to hold.
DEFAULT_REF_TEMP_C = 23.0
#: A reference wrench beyond this many full scales of the design on any axis is no load the
#: mechanism can have carried inside its joint box: a corrupt row, a unit error, another design.
MAX_FULL_SCALES = 3.0
#: Below this many samples the held-out scoring has too few independent blocks to mean much.
MIN_SAMPLES = 2000
#: A log sampled more slowly than this (median step, s) is no sensor stream: most likely its
#: time is in milliseconds.
MAX_SAMPLE_STEP_S = 1.0
#: A log whose rows are this many times closer or further apart than its header's ``rate_hz``
#: says has its time in other units (a millisecond log at 1 kHz passes the step's limit).
RATE_MISMATCH = 5.0
#: Samples per piece when a per-sample map of the whole log is computed (bounds the memory
#: the model's intermediate arrays take on long logs).
PIECE = 50_000
#: What a causal view of a log shares with the log: everything but the look-ahead features.
_SHARED_WITH_CAUSAL = ("model", "residual", "residual_pct", "position_mm",
                       "torque_map", "angle_jacobian", "geometry_jacobian",
                       "residual_joint_torque", "_play_cache", "_lag_cache")


class DiagnosisInputError(UserError):
    """The log cannot be diagnosed; the message names the problem."""


@contextlib.contextmanager
def errors_naming(path):
    """Within the block, a :class:`DiagnosisInputError` says which log it is about (the
    diagnosis's checks name what is wrong in the log, not the file)."""
    try:
        yield
    except DiagnosisInputError as exc:
        raise UserError(f"{path}: {exc}") from None


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
    #: The whole log's median sample step, s (a piece of a log keeps its log's step).
    step: float = 0.0
    #: History state entering this piece of a log (play and lag outputs of the sample before
    #: it, keyed by operator); empty for a whole log or its first piece.
    carry: dict = field(default_factory=dict, repr=False)
    #: Index whose history state the next piece needs (its ``carry``), and that state.
    handoff: int | None = None
    carry_out: dict = field(default_factory=dict, repr=False)
    #: The features a board can compute (``causal_view``): the joint speed by the board's
    #: filtered difference, reversals where the counts show them (no look-ahead).
    causal: bool = False
    #: The velocity's local fit, (half width in samples, degree), chosen once for the whole
    #: log (``terms.friction_velocity_window``); None: ``signals.smooth_velocity``'s default.
    velocity_window: tuple[int, int] | None = None

    def __post_init__(self):
        if not self.step:
            self.step = float(np.median(np.diff(self.t))) if len(self.t) > 1 else 1.0

    @classmethod
    def from_log(cls, log: LogData, design: Design,
                 ref_temp_c: float = DEFAULT_REF_TEMP_C) -> "GapData":
        check_log(log, design)
        temp = log.temp_c
        fs = full_scale(design)
        # Contiguous copies: a log's columns may be views into its whole table, which then
        # need not stay in memory.
        data = cls(design=design, params=Params.from_design(design),
                   t=np.ascontiguousarray(log.t, float),
                   theta=np.ascontiguousarray(log.theta, float),
                   reference=np.ascontiguousarray(log.wrench, float),
                   temp_c=None if temp is None else np.ascontiguousarray(temp, float),
                   fs=fs, ref_temp_c=ref_temp_c)
        if not np.all(np.isfinite(data.model)):
            raise DiagnosisInputError("the analytical model has no solution for some logged "
                                      "angles: wrong design for this log?")
        return data

    def __len__(self) -> int:
        return len(self.t)

    def piece(self, start: int, stop: int, carry: dict | None = None,
              handoff: int | None = None) -> "GapData":
        """Samples [start, stop) as a log of their own that continues this one's history:
        ``carry`` is the state a previous piece handed off (see ``handoff``, an index into
        this log, whose state the new piece records in its ``carry_out``)."""
        sl = slice(start, stop)
        return GapData(design=self.design, params=self.params, t=self.t[sl],
                       theta=self.theta[sl], reference=self.reference[sl],
                       temp_c=None if self.temp_c is None else self.temp_c[sl], fs=self.fs,
                       ref_temp_c=self.ref_temp_c, step=self.step, carry=dict(carry or {}),
                       handoff=None if handoff is None else handoff - start,
                       causal=self.causal, velocity_window=self.velocity_window)

    def _by_piece(self, fn) -> np.ndarray:
        if len(self) <= PIECE:
            return fn(slice(None))
        parts = [fn(slice(a, a + PIECE)) for a in range(0, len(self), PIECE)]
        return np.concatenate(parts, axis=0)

    # -- history features, continued across pieces ---------------------------------------

    def _continued(self, key, compute):
        """``compute(y0)`` -> outputs (n, ...) of a history operator started from ``y0`` (None:
        from rest at the first sample); records the state at ``handoff``."""
        out = compute(self.carry.get(key))
        if self.handoff is not None and 0 <= self.handoff < len(self):
            self.carry_out[key] = np.array(out[self.handoff], copy=True)
        return out

    def play_state(self, radii) -> np.ndarray:
        """Normalised play states of the encoder angles (``signals.play_state``), (n, 6, r)."""
        radii = tuple(float(r) for r in radii)
        cache = self.__dict__.setdefault("_play_cache", {})
        if radii not in cache:
            cache[radii] = self._play_state(radii)
        return cache[radii]

    def _play_state(self, radii: tuple) -> np.ndarray:
        """:meth:`play_state` computed ``PIECE`` samples at a time, each piece's plays started
        from the outputs of the sample before it: the same numbers (a play is a running clamp,
        exact however it is cut), while the scan's intermediate arrays, several times the
        states' size, stay one piece's (a long log's whole-log states would take gigabytes)."""
        key = ("play", radii)
        r = np.asarray(radii)
        out = np.empty(self.theta.shape + (len(radii),))
        y0 = self.carry.get(key)
        for a in range(0, len(self), PIECE):
            theta = self.theta[a:a + PIECE]
            y = play_output(theta, radii, y0)
            if self.handoff is not None and a <= self.handoff < a + len(theta):
                self.carry_out[key] = np.array(y[self.handoff - a], copy=True)
            y0 = np.array(y[-1], copy=True)
            np.subtract(theta[:, :, None], y, out=y)          # the state, in place
            np.divide(y, r, out=out[a:a + len(theta)])
        return out

    def lagged_temp(self, tau_s: float) -> np.ndarray:
        """The temperature through a first-order lag of ``tau_s`` (``signals.lagged``)."""
        cache = self.__dict__.setdefault("_lag_cache", {})
        if tau_s not in cache:
            cache[tau_s] = self._continued(("lag", float(tau_s)), lambda y0: lagged(
                self.temp_c, self.t, tau_s, step=self.step, y0=y0))
        return cache[tau_s]

    def dwell_ramp(self, switch_rad: float, max_dwell_s: float, still: float,
                   power: float) -> np.ndarray:
        """The direction of motion with each reversal spread over its dwell
        (``signals.dwell_ramps``), (n, 6)."""
        state = self.play_state((switch_rad,))[:, :, 0]
        if self.causal:
            return state        # a board knows of a reversal once the encoder shows it
        key = (switch_rad, max_dwell_s, still, power)
        cache = self.__dict__.setdefault("_ramp_cache", {})
        if key not in cache:
            cache[key] = dwell_ramps(self.theta, state, self.t, max_dwell_s, still, power)
        return cache[key]

    @functools.cached_property
    def smooth_velocity(self) -> np.ndarray:
        """Encoder angular velocity by a local fit (``signals.smooth_velocity``, over
        ``velocity_window`` when chosen); in a causal view, the board's filtered count
        difference (:func:`board_speed`)."""
        if self.causal:
            return board_speed(self.theta, self.t, self.step)
        if self.velocity_window is None:
            return smooth_velocity(self.theta, self.t, step=self.step)
        half, degree = self.velocity_window
        return smooth_velocity(self.theta, self.t, half, step=self.step, degree=degree)

    def causal_view(self) -> "GapData":
        """The same log with the features a board computes from past samples only (the
        model, residual and sensitivity maps shared, not recomputed)."""
        view = dataclasses.replace(self, carry=dict(self.carry), carry_out={}, causal=True)
        for name in _SHARED_WITH_CAUSAL:
            if name in self.__dict__:
                view.__dict__[name] = self.__dict__[name]
        return view

    @functools.cached_property
    def model(self) -> np.ndarray:
        return self._by_piece(lambda sl: wrench(self.params, self.theta[sl]))

    @functools.cached_property
    def residual(self) -> np.ndarray:
        """Reference minus model: what the analytical model misses."""
        return self.reference - self.model

    @functools.cached_property
    def residual_pct(self) -> np.ndarray:
        return 100.0 * self.residual / self.fs

    @functools.cached_property
    def velocity(self) -> np.ndarray:
        """Encoder angular velocity, rad/s (central differences; in a causal view, the
        board's speed: a central difference looks ahead)."""
        if self.causal:
            return self.smooth_velocity
        return np.gradient(self.theta, self.t, axis=0)

    @functools.cached_property
    def position_mm(self) -> np.ndarray:
        return self._by_piece(lambda sl: forward_kinematics(self.params,
                                                            self.theta[sl, :3]) * 1e3)

    @functools.cached_property
    def torque_map(self) -> np.ndarray:
        return sensitivity.torque_map(self.params, self.theta)

    @functools.cached_property
    def angle_jacobian(self) -> np.ndarray:
        return sensitivity.angle_jacobian(self.params, self.theta, base=self.model)

    @functools.cached_property
    def geometry_jacobian(self) -> np.ndarray:
        return sensitivity.geometry_jacobian(self.params, self.theta, base=self.model)

    def joint_torque_of(self, wrench_error: np.ndarray, index=slice(None)) -> np.ndarray:
        """A wrench error (N, N*m) at the samples ``index`` expressed as the extra joint
        torques that would explain it, G^-1 r (N*m), computed piece by piece."""
        theta = self.theta[index]
        out = np.empty_like(wrench_error)
        for a in range(0, len(theta), PIECE):
            sl = slice(a, a + PIECE)
            g = sensitivity.torque_map(self.params, theta[sl])
            out[sl] = np.linalg.solve(g, wrench_error[sl][..., None])[..., 0]
        return out

    @functools.cached_property
    def residual_joint_torque(self) -> np.ndarray:
        """The residual expressed as the extra joint torques that would explain it,
        G^-1 r (N*m): makes torque-side effects (hysteresis, friction) visible per joint."""
        return self.joint_torque_of(self.residual)


def board_speed(theta: np.ndarray, t: np.ndarray, step: float) -> np.ndarray:
    """The joint speed a board's friction takes from the counts, rad/s: the calibrated
    model's filtered difference and its lead, with a new calibration's settings; no speed
    across lost samples."""
    v = filtered_speed(theta / ENCODER_COUNT_RAD, step, DEFAULT_SPEED_FILTER_S,
                       periods_between(t, step))
    return led_speed(v, step, DEFAULT_SPEED_FILTER_S, DEFAULT_SPEED_LEAD_S)[0]


def _stated_rate_hz(meta: dict) -> float | None:
    """The rate a log's header states (``rate_hz``, written by ``delta6 log``), if any."""
    try:
        value = float(meta.get("rate_hz", ""))
    except ValueError:
        return None
    return value if np.isfinite(value) and value > 0 else None


def check_log(log: LogData, design: Design, min_samples: int = MIN_SAMPLES) -> None:
    """The checks a log passes before any model is fitted to it or scored on it (the
    diagnosis, ``delta6 calibrate``, ``delta6 evaluate``): enough samples, finite values, time
    in seconds and strictly increasing, angles without a count wrap-around and inside the
    joint box, reference wrenches the design can carry. Each failure is one
    :class:`DiagnosisInputError` naming the problem."""
    n = len(log.t)
    if n < min_samples:
        why = " for time-blocked held-out scoring" if min_samples == MIN_SAMPLES else ""
        raise DiagnosisInputError(f"too few samples: {n} (at least {min_samples}{why})")
    for name, values in (("t", log.t), ("theta_e", log.theta), ("wrench", log.wrench)):
        if not np.all(np.isfinite(values)):
            raise DiagnosisInputError(f"NaN or infinite {name} values in the log")
    steps = np.diff(log.t)
    if np.any(steps <= 0):
        raise DiagnosisInputError("time is not strictly increasing")
    step = float(np.median(steps)) if n > 1 else 0.0
    if step > MAX_SAMPLE_STEP_S:
        raise DiagnosisInputError(
            f"the log's median sample step is {step:.4g} s ({1 / step:.3g} Hz), slower than "
            f"any force sensor's stream: t must be in seconds (milliseconds?)")
    stated = _stated_rate_hz(getattr(log, "meta", None) or {})   # a twin run has no header
    if step > 0 and stated and not 1 / RATE_MISMATCH < step * stated < RATE_MISMATCH:
        raise DiagnosisInputError(
            f"the log's header says rate_hz={stated:g}, but its rows are {step:.4g} apart in t "
            f"({1 / step:.3g} Hz): t must be in seconds (milliseconds?)")
    # A wrapped 14-bit count jumps by a whole turn; no two samples inside the (tolerated) joint
    # box are that far apart, whatever the design.
    delta = np.abs(np.diff(log.theta, axis=0))
    jumps = (np.abs(delta - 2 * np.pi) < np.pi / 4) & (delta > 3 * design.joint_limit_rad)
    if jumps.any():
        row, joint = (int(v) for v in np.argwhere(jumps)[0])
        step = log.theta[row + 1, joint] - log.theta[row, joint]
        raise DiagnosisInputError(
            f"theta_e{joint + 1} jumps by {step:+.4g} rad between t = {log.t[row]:g} and "
            f"{log.t[row + 1]:g} s: a count wrap-around (angles must be unwrapped, relative to "
            "the encoder zeros) or a corrupt row")
    temp = log.temp_c
    if temp is not None and not np.all(np.isfinite(temp)):
        raise DiagnosisInputError("NaN or infinite temp_c values in the log")
    fs = full_scale(design)
    over = np.abs(log.wrench) > MAX_FULL_SCALES * fs
    if over.any():
        row, axis, samples = _first_of(over)
        unit = "N" if axis < 3 else "N*m"
        raise DiagnosisInputError(
            f"{samples} a reference wrench far outside "
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
    if outside.any():
        # A few: corrupt rows. Scored, they were wrenches where the board reports none (up to
        # 10^5 % FS); fitted, they bent a calibration. Removed, a row reads as a lost sample.
        row, joint, samples = _first_of(outside)
        raise DiagnosisInputError(
            f"{samples} an encoder angle far outside the "
            f"joint box, the first at t = {log.t[row]:g} s: theta_e{joint + 1} = "
            f"{log.theta[row, joint]:.4g} rad (|theta_e| up to {1.5 * limit:.2f} is accepted): "
            "corrupt rows (delete them: a missing row reads as a lost sample)")


def _first_of(bad: np.ndarray) -> tuple[int, int, str]:
    """(row, column) of the first True in ``bad`` (samples, columns), and how many samples
    have one: "1 sample has", "3 samples have"."""
    row, column = (int(v) for v in np.argwhere(bad)[0])
    n = int(bad.any(axis=1).sum())
    return row, column, f"{n} {'sample has' if n == 1 else 'samples have'}"


#: A joint whose angle spreads less than this over a log was not moved (or its encoder is
#: stuck): nothing about it can be fitted or learned.
MIN_JOINT_SPREAD_RAD = 2e-3
#: A joint whose count stands exactly still this long while another joint moves is reported:
#: an encoder frozen for a stretch of the log (a real hold is rarely this long under motion).
FROZEN_S = 10.0


def check_motion(theta: np.ndarray, source: str = "the log",
                 why: str = "a model cannot learn how the wrench depends on a joint it never "
                            "saw move") -> None:
    """Refuse a log in which some joint hardly moves (one line naming the joint)."""
    theta = np.asarray(theta, dtype=float)
    spread = np.array([np.std(col[np.isfinite(col)]) if np.isfinite(col).any() else 0.0
                       for col in theta.T])
    still = np.flatnonzero(spread < MIN_JOINT_SPREAD_RAD)
    if len(still):
        joints = ", ".join(f"theta_e{j + 1}" for j in still)
        raise UserError(f"{source}: {joints} hardly move{'s' if len(still) == 1 else ''} "
                        f"(angle spread {spread[still].max():.2g} rad, at least "
                        f"{MIN_JOINT_SPREAD_RAD:g} needed; a stuck encoder?): {why}; record a "
                        "run that moves every joint")


def frozen_stretches(t: np.ndarray, theta: np.ndarray, min_s: float = FROZEN_S) -> list[str]:
    """One note per stretch of at least ``min_s`` in which a joint's angle stands exactly still
    while another joint moves (an encoder frozen for a while)."""
    t = np.asarray(t, dtype=float)
    theta = np.asarray(theta, dtype=float)
    if len(t) < 2:
        return []
    same = np.diff(theta, axis=0) == 0                      # (n-1, 6)
    moving = (~same).sum(axis=1)                            # joints that moved, per step
    notes = []
    for j in range(theta.shape[1]):
        still = same[:, j] & (moving > 0)                   # j still, another one moved
        edges = np.flatnonzero(np.diff(np.r_[0, still.astype(np.int8), 0]))
        for start, stop in zip(edges[::2], edges[1::2]):
            span = t[stop] - t[start]
            if span >= min_s:
                notes.append(f"note: theta_e{j + 1} stands exactly still for {span:.0f} s from "
                             f"t = {t[start]:g} s while other joints move (a frozen encoder?)")
    return notes
