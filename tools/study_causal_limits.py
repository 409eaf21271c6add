"""What a causal calibration cannot correct: the figures behind docs/calibration.md's
"Limits of a causal correction".

    .venv/bin/python tools/study_causal_limits.py                 # both studies, ~5 min
    .venv/bin/python tools/study_causal_limits.py --study friction --cal-duration 600

- ``friction``: the ``joint_friction`` single-effect scenario. The friction features (smooth
  signs of a joint speed, the speed, the 1.5-count direction play) fitted by least squares on
  the calibration run's analytical residual, scored (p99, % FS) on an unseen run of the same
  unit, for speed estimates: the diagnosis's centred local fit (two samples of the future),
  the same delayed by one and two samples (two is its causal form), and causal estimates
  (the board's filtered difference, a quadratic fit over the past samples, the filtered speed
  led by a filtered acceleration).
- ``backlash``: the ``paper`` unit. ``delta6 calibrate``'s fit with the explicit effect set,
  without backlash, with the causal backlash correction, with an oracle that knows where the
  link sits in the play (the twin's hidden angle: not available to any board), and the same
  unit without backlash at all (the ablation); plus how often the link sits inside the play or
  on the other flank than the causal direction says.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from delta6 import twin
from delta6.calibration import calibrate
from delta6.core import calibrated as calibrated_mod
from delta6.core.calibrated import CalibratedModel, counts_from_angles
from delta6.core.model import AXES, ENCODER_COUNT_RAD
from delta6.core.operators import affine_scan, play
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.spec import full_scale
from delta6.core.workspace import load_checked
from delta6.diagnosis.data import GapData
from delta6.diagnosis.signals import smooth_velocity

SET = ["stiffness_mismatch", "joint_friction", "link_compliance", "encoder_offset",
       "spring_hysteresis"]


def row(label, values) -> str:
    return f"| {label} | " + " | ".join(f"{v:.2f}" for v in values) + " |"


def header(first: str) -> str:
    return f"| {first} | " + " | ".join(AXES) + " |\n|---|" + "---|" * 6


def lowpass(u, tau, dt):
    a = tau / (tau + dt)
    return affine_scan(np.full(u.shape, a), (1 - a) * u, np.zeros(u.shape[1]))


def delayed(v, k):
    return np.vstack([np.repeat(v[:1], k, 0), v[:len(v) - k]]) if k else v


def past_quadratic_speed(theta, n, dt):
    """Slope at the newest sample of a quadratic fitted to the last n samples."""
    k = np.arange(-(n - 1), 1, dtype=float)
    w = np.linalg.pinv(np.stack([np.ones(n), k, k ** 2], 1))[1]
    return sum(wi * delayed(theta, n - 1 - i) for i, wi in enumerate(w)) / dt


def speeds(run, dt):
    x = counts_from_angles(run.theta)
    theta = x * ENCODER_COUNT_RAD
    board = lowpass(np.diff(theta, axis=0, prepend=theta[:1]) / dt, 0.02, dt)
    # The diagnosis's fit until 2026-11 (a line over two samples either side): the table
    # asks what a delay of one or two samples costs such a fit.
    centred = smooth_velocity(run.theta, run.t, half_width=2, degree=1)
    accel = lowpass(np.diff(board, axis=0, prepend=board[:1]) / dt, 0.04, dt)
    return x, {
        "centred local fit (the diagnosis; 2 samples of the future)": centred,
        "the same, 1 sample late": delayed(centred, 1),
        "the same, 2 samples late (its causal form)": delayed(centred, 2),
        "board: filtered difference, 20 ms (causal)": board,
        "quadratic fit over the past 7 samples (causal)": past_quadratic_speed(theta, 7, dt),
        "filtered speed + 20 ms x filtered acceleration (causal)": board + 0.02 * accel,
    }


def play_states(x, radii):
    """(x - play_r(x)) / r for play radii r (counts): rate-independent, in [-1, 1]."""
    r = np.asarray(radii, dtype=float)
    return (x[:, :, None] - play(x[:, :, None], r, np.repeat(x[0][:, None], len(r), 1))) / r


def friction_columns(data, x, v, bristles=False):
    direction = play_states(x, [1.5])[:, :, 0]
    if bristles:     # a LuGre-like bristle state: friction from small plays of the count
        feats = np.concatenate([play_states(x, [1, 1.5, 2, 3, 4, 6]), v[:, :, None]], -1)
    else:
        feats = np.stack([np.tanh(v / s) for s in (0.003, 0.01, 0.04)] + [v, direction], -1)
    cols = data.torque_map[:, :, :, None] * feats[:, None, :, :]
    return cols.reshape(len(data), 6, -1) / data.fs[None, :, None]


def study_friction(design, args) -> None:
    name = "joint_friction"
    fit_run = twin.simulate(design, twin.scenario_effects(name, seed=1),
                            duration_s=args.cal_duration, rate_hz=50, seed=1, scenario=name)
    check = twin.simulate(duration_s=args.eval_duration, rate_hz=50,
                          **twin.same_unit(fit_run.truth, 2))
    floor = twin.simulate(**twin.without(check.truth, [name]))
    fs = full_scale(design)
    dt = 0.02
    runs = []
    for run in (fit_run, check):
        data = GapData.from_log(run, design)
        x, by_kind = speeds(run, dt)
        runs.append((data, x, by_kind))
    lines = ["### friction: p99 on the unseen run (% FS) by speed estimate", "",
             header("speed estimate")]
    lines.append(row("floor (the run without friction)",
                     np.percentile(np.abs(floor.model_wrench() - floor.wrench) / fs * 100,
                                   99, 0)))
    (fd, fx, fk), (cd, cx, ck) = runs
    board = "board: filtered difference, 20 ms (causal)"
    for kind, bristles in [(k, False) for k in fk] + [(board, True)]:
        a = friction_columns(fd, fx, fk[kind], bristles)
        coef = np.linalg.lstsq(a.reshape(-1, a.shape[-1]), (fd.residual / fd.fs).reshape(-1),
                               rcond=None)[0]
        err = np.abs(cd.residual / cd.fs - friction_columns(cd, cx, ck[kind], bristles) @ coef)
        label = ("bristle states: plays of 1, 1.5, 2, 3, 4, 6 counts, + the board's speed "
                 "(causal)") if bristles else kind
        lines.append(row(label, np.percentile(100 * err, 99, 0)))
    print("\n".join(lines) + "\n", flush=True)


def still_seconds(x, dt):
    """How long each joint's count has stood still, s."""
    moved = np.vstack([np.ones((1, x.shape[1]), bool), np.diff(x, axis=0) != 0])
    out = np.zeros_like(x)
    run = np.zeros(x.shape[1])
    for i in range(len(x)):
        run = np.where(moved[i], 0.0, run + dt)
        out[i] = run
    return out


def dwell_guess(design, cal, fit_run, check, dt=0.02):
    """On top of the causal calibration: the direction scaled by ramps of the time the encoder
    has stood still (40 ms to 0.4 s), fitted by least squares: a causal guess that the link has
    left its flank while the encoder waits."""
    fs = full_scale(design)
    model = CalibratedModel(design, cal)

    def parts(run):
        data = GapData.from_log(run, design)
        x = counts_from_angles(run.theta)
        terms, _ = model.joint_terms(x, dt)
        left = (run.wrench - model.wrench_from_terms(terms.theta, terms.torque)) / fs
        still = still_seconds(x, dt)
        feats = np.stack([terms.direction * np.minimum(still / t, 1.0)
                          for t in (0.04, 0.1, 0.2, 0.4)], -1)
        cols = data.angle_jacobian[:, :, :, None] * 0.5 * feats[:, None, :, :]
        return left, cols.reshape(len(data), 6, -1) / fs[None, :, None]

    left, cols = parts(fit_run)
    coef = np.linalg.lstsq(cols.reshape(-1, cols.shape[-1]), left.reshape(-1), rcond=None)[0]
    left, cols = parts(check)
    return np.percentile(np.abs(left - cols @ coef) * 100, 99, 0)


def study_backlash(design, args) -> None:
    fit_run = twin.simulate(design, twin.scenario_effects("paper", seed=1),
                            duration_s=args.cal_duration, rate_hz=50, seed=1, scenario="paper")
    check = twin.simulate(duration_s=args.eval_duration, rate_hz=50,
                          **twin.same_unit(fit_run.truth, 2))
    fs = full_scale(design)
    inside = {}
    for run in (fit_run, check):
        u = run.true_angles - counts_from_angles(run.theta) * ENCODER_COUNT_RAD
        inside[len(run.t)] = u - 0.5 * (u.max(0) + u.min(0))   # link minus encoder, centred

    original = CalibratedModel.joint_terms
    oracle = {"on": None}

    def joint_terms(self, counts, dt, state=None):
        # The oracles: the angle of the link itself, wherever it sits in the play, for the
        # angle side ("angle"), or for the history features (hysteresis, speed) too ("all").
        c = self.cal
        if oracle["on"] is None:
            return original(self, counts, dt, state)
        link = inside[len(counts)]
        if oracle["on"] == "all":
            counts = counts + link / ENCODER_COUNT_RAD
            link = np.zeros_like(link)
        terms, after = original(self, counts, dt, state)
        extra = link - 0.5 * c.backlash_play_rad * terms.direction
        terms.theta = terms.theta + extra
        terms.torque = terms.torque + self.design.k * c.rate_ratio * extra
        return terms, after

    def score(effects, fit_on, check_on):
        fit = calibrate(fit_on, design, effects=effects)
        w = CalibratedModel(design, fit.calibration).predict(check_on)
        return np.percentile(np.abs(w - check_on.wrench) / fs * 100, 99, 0), fit.calibration

    lines = ["### backlash on the paper unit: calibrated p99 on the unseen run (% FS)", "",
             header("backlash correction")]
    p, _ = score(SET, fit_run, check)
    lines.append(row("none", p))
    p, cal = score(SET + ["backlash"], fit_run, check)
    lines.append(row("causal (direction play on the count)", p))
    lines.append(row("causal, + a guess from how long the encoder has stood still",
                     dwell_guess(design, cal, fit_run, check)))
    calibrated_mod.CalibratedModel.joint_terms = joint_terms
    try:
        for kind, label in (("angle", "oracle: the link's hidden angle on the angle side"),
                            ("all", "oracle: ... and for the hysteresis and speed too")):
            oracle["on"] = kind
            p, _ = score(SET + ["backlash"], fit_run, check)
            lines.append(row(label, p))
    finally:
        oracle["on"] = None
        calibrated_mod.CalibratedModel.joint_terms = original
    bare_fit = twin.simulate(**twin.without(fit_run.truth, ["backlash"]))
    bare_check = twin.simulate(**twin.without(check.truth, ["backlash"]))
    p, _ = score(SET, bare_fit, bare_check)
    lines.append(row("the same unit without backlash (ablation)", p))
    u = inside[len(check.t)]
    truth = next(e for e in check.truth["effects"] if e["name"] == "backlash")
    half = 0.5 * np.asarray(truth["parameters"]["play_rad"], dtype=float) * np.ones(6)
    direction, _ = CalibratedModel(design, cal).joint_terms(counts_from_angles(check.theta),
                                                            0.02)
    lines += ["", f"fitted play (rad): {' '.join(f'{v:.4f}' for v in cal.backlash_play_rad)}; "
              f"the unit's: {' '.join(f'{v:.4f}' for v in 2 * half)}",
              "link inside the play (more than a quarter of the half-play from a flank), "
              "share of samples: " + " ".join(
                  f"{v:.2f}" for v in (np.abs(np.abs(u) - half) > 0.25 * half).mean(0)),
              "link on the other flank than the causal direction says, share of samples: "
              + " ".join(f"{v:.2f}" for v in (np.sign(u) != np.sign(direction.direction))
                         .mean(0))]
    print("\n".join(lines) + "\n", flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--study", choices=("friction", "backlash", "both"), default="both")
    parser.add_argument("--cal-duration", type=float, default=2000.0)
    parser.add_argument("--eval-duration", type=float, default=600.0)
    args = parser.parse_args(argv)
    design = load_checked(DEFAULT_DESIGN)
    if args.study in ("friction", "both"):
        study_friction(design, args)
    if args.study in ("backlash", "both"):
        study_backlash(design, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
