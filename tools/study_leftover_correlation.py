"""Would the joints' correlated torque noise raise the leftover angle test's power? The figures
behind docs/diagnosis.md's note on it ("What is left"). Development seeds only (below 10,000).

    .venv/bin/python tools/study_leftover_correlation.py                 # all three, ~6 min
    .venv/bin/python tools/study_leftover_correlation.py --study noise   # ~15 s
    .venv/bin/python tools/study_leftover_correlation.py --study runs --seeds 4102 4103 \
        --withhold geometry_error         # proximal encoder errors without the geometry family
    .venv/bin/python tools/study_leftover_correlation.py --study nuisance \
        --withhold geometry_error         # the angle test against a nuisance basis, ~3 min
    .venv/bin/python tools/study_leftover_correlation.py --study nuisance-sim   # ~3 min

The leftover's white noise comes mostly from the reference sensor's wrench noise mapped through
G^-1, so it is correlated across joints. The candidate test for joint j runs the verdict's angle
test (``leftover.angle_test``) on the conditional residual tau_j - b_j (tau_-j - S_-j), with
b_j = Omega_j,-j Omega_-j,-j^-1 (Omega: the joints' white-noise covariance from first
differences, robust scales and the Gnanadesikan-Kettenring cross terms) and S_k the other
joints' own-angle polynomials (fitted on the whole log, so that another joint's curve in its
own angle does not leak into joint j).

- ``noise``: on runs without effects, the correlation of the joints' white torque noise, the
  conditional residual's noise against the joint's own, and whether the leftover is white
  (the sd of block means against the white level).
- ``runs``: twin runs diagnosed as the blind benchmark's unknown cases (the three newest
  families withheld): an encoder's periodic error on one or two joints, the stiffening spring,
  the harness, no effect. Per joint: the bend (``gap_benchmark.joint_bends``), what the
  leftover's held-out angle fit explains, the leftover's slow part that is no function of the
  joint's own angle, and the angle test's p on the joint's torque (old), on the conditional
  residual (new), and on the joint's own-angle curve (fitted on the whole log) plus white
  noise at the joint's level in place of the rest (the median of five draws: what the test
  would give if only the white noise stood in its way); the verdict's joints with each.
- ``white``: a white leftover (a run without effects) with an encoder-error-like curve added
  on one joint (its footprint G^-1 dW/dtheta_j times a smooth function of the angle, straight
  part removed): the power of both tests; and the level on simulated white noise with the
  sensor's cross-axis covariance, alone and with a curve on another joint or a pose-dependent
  force on the plate.
- ``nuisance``: the same runs, the angle test against a nuisance basis: per joint, the
  held-out gain of [own-angle polynomial + nuisance] over [constant + nuisance], both fitted on
  the same training stretches (``beyond_nuisance_test``), with the nuisance the other five
  joints' angles, linear and quadratic with their cross products (``others``), those plus the
  cross products with the joint's own angle (``others+cross``), or the joint torques of a
  wrench on the plate affine in the plate's position (``plate``); per joint old and new p, and
  the verdict's joints and shape with each.
- ``nuisance-sim``: the nuisance test's power and level by simulation on the white leftover
  of a run without effects: a curve on one joint (alone, and beside a pose-dependent slow part
  of 0.1 or 0.2 mN*m on the joint: what of the curve's held-out fit survives); and the share of
  joints without a curve of their own that pass, on white noise, noise correlated in time, a
  curve on another joint, and a pose-dependent force on the plate.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from delta6 import twin
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.workspace import load_checked
from delta6.diagnosis import leftover, sensitivity
from delta6.diagnosis.run import diagnose
from delta6.diagnosis.terms import TERMS
from delta6.evaluation import gap_benchmark
from delta6.link.logfile import LogData

NEWEST = ("nonlinear_spring", "encoder_periodic_error", "harness")
LEVEL = leftover.ANGLE_ALPHA / 6
DURATION = 400.0
EPE = "encoder_periodic_error"
#: (seed, [(effect, magnitude, joints or None)]): development seeds.
RUNS = [
    (4101, [(EPE, 0.8, [1])]), (4102, [(EPE, 0.8, [2])]), (4103, [(EPE, 0.8, [3])]),
    (4118, [(EPE, 0.9, [2])]), (4119, [(EPE, 0.9, [1])]),
    (4104, [(EPE, 0.8, [1, 2])]), (4105, [(EPE, 0.8, [2, 3])]), (4106, [(EPE, 0.8, [1, 3])]),
    (4120, [(EPE, 0.9, [1, 2])]),
    (4107, [(EPE, 0.8, [4])]), (4108, [(EPE, 0.8, [5, 6])]), (4109, [(EPE, 0.8, [2, 5])]),
    (4110, [(EPE, 0.7, [3, 4])]),
    (4111, [("nonlinear_spring", 0.8, None)]), (4112, [("nonlinear_spring", 0.7, [2])]),
    (4113, [("harness", 0.8, None)]), (4114, [("harness", 0.7, None)]),
    (4115, []), (4116, []), (4117, []),
]


def robust_cov(d: np.ndarray) -> np.ndarray:
    """The white-noise covariance of the columns whose first differences are ``d``."""
    def mad(x):
        return 1.4826 * np.median(np.abs(x - np.median(x, axis=0)), axis=0)
    sd = mad(d)
    z = d / sd
    c = np.eye(d.shape[1])
    for i in range(d.shape[1]):
        for j in range(i + 1, d.shape[1]):
            a, b = mad(z[:, i] + z[:, j]), mad(z[:, i] - z[:, j])
            c[i, j] = c[j, i] = (a * a - b * b) / (a * a + b * b)
    return c * np.outer(sd, sd) / 2.0


def own_poly(angle: np.ndarray) -> np.ndarray:
    s = (angle - angle.mean()) / (angle.std() or 1.0)
    return np.stack([s**k for k in range(leftover.ANGLE_DEGREE + 1)], axis=1)


def beyond_own_angle(tau: np.ndarray, theta: np.ndarray) -> np.ndarray:
    out = np.empty_like(tau)
    for k in range(tau.shape[1]):
        b = own_poly(theta[:, k])
        out[:, k] = tau[:, k] - b @ np.linalg.lstsq(b, tau[:, k], rcond=None)[0]
    return out


def conditional(tau: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Per joint, its torque less what the other joints' noise predicts of its own."""
    omega = robust_cov(np.diff(tau, axis=0))
    pred = beyond_own_angle(tau, theta)
    out = np.empty_like(tau)
    for j in range(6):
        o = [k for k in range(6) if k != j]
        out[:, j] = tau[:, j] - pred[:, o] @ np.linalg.solve(omega[np.ix_(o, o)], omega[o, j])
    return out


def run(design, seed: int, effects, withhold=()) -> dict:
    """A twin run diagnosed without the newest families (and ``withhold``); the leftover
    verdict's input."""
    made = [twin.make_effect(name, seed=seed + 100_000 * i, magnitude=m, joints=joints,
                             formulation=twin.random_effect(name, seed=seed + 100_000 * i)
                             .formulation)
            for i, (name, m, joints) in enumerate(effects)]

    def simulate(active):
        return twin.simulate(design, active, duration_s=DURATION, rate_hz=50.0, seed=seed,
                             record_temp=True)
    r = simulate(made)
    seen = {}
    analyse = leftover.analyse

    def spy(data, leftover_fs):     # the verdict's own input, as diagnose hands it over
        seen.update(data=data, left=leftover_fs.copy())
        return analyse(data, leftover_fs)
    leftover.analyse = spy
    try:
        verdict = diagnose(LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c),
                           design, seed=0, terms=[t for t in TERMS if t.name not in NEWEST + tuple(withhold)])
    finally:
        leftover.analyse = analyse
    bends = None
    if made and made[0].NAME in gap_benchmark.BENT_EFFECTS and effects[0][2]:
        bends = gap_benchmark.joint_bends(design, made[0], simulate, simulate([]))
    data = seen["data"]
    idx = np.arange(0, len(data), max(1, len(data) // leftover.SHAPE_SAMPLES))
    return {"data": data, "left": seen["left"], "verdict": verdict, "bends": bends,
            "tau": data.joint_torque_of(seen["left"][idx] * data.fs, idx),
            "theta": data.theta[idx], "formulations": [e.formulation for e in made]}


def verdict_with(data, left, tests) -> dict:
    """The leftover verdict with each joint's angle test taken from ``tests``."""
    calls = iter(tests)
    angle_test = leftover.angle_test
    leftover.angle_test = lambda *a, **k: next(calls)
    try:
        return leftover.analyse(data, left)
    finally:
        leftover.angle_test = angle_test


def verdict_joints(data, left, tests) -> list[int]:
    """The leftover verdict's joints with each joint's angle test taken from ``tests``."""
    return verdict_with(data, left, tests)["joints"]


def study_noise(design) -> None:
    np.set_printoptions(precision=2, suppress=True, linewidth=120)
    for seed in (4115, 4116, 4117):
        c = run(design, seed, [])
        tau = c["data"].joint_torque_of(c["left"] * c["data"].fs)
        omega = robust_cov(np.diff(tau, axis=0))
        sd = np.sqrt(np.diag(omega))
        corr = omega / np.outer(sd, sd)
        ratio = 1.0 / np.sqrt(np.diag(omega) * np.diag(np.linalg.inv(omega)))
        blocks = tau[: len(tau) // 1000 * 1000].reshape(-1, 1000, 6).mean(axis=1)
        print(f"seed {seed}: white torque noise (mN*m) {1e3 * sd}")
        print(f"  correlation across joints:\n{corr}")
        print(f"  conditional residual's noise / joint's own: {ratio}")
        print(f"  sd of 20-s block means x sqrt(1000) / white: {blocks.std(0) * 31.62 / sd}")


def study_runs(design, seeds=None, withhold=()) -> None:
    print("per run; per joint: bend | leftover's held-out angle fit | slow part beyond the "
          "own-angle curve (mN*m) | p old | p new | p if the rest were white "
          "(* <= 1.67e-4)")
    rng = np.random.default_rng(1)
    false = {"old": 0, "new": 0}
    false_verdict = {"old": 0, "new": 0}
    for seed, effects in RUNS:
        if seeds and seed not in seeds:
            continue
        c = run(design, seed, effects, withhold)
        tau, theta = c["tau"], c["theta"]
        tests = {"old": [leftover.angle_test(tau[:, j], theta[:, j]) for j in range(6)]}
        e = conditional(tau, theta)
        tests["new"] = [leftover.angle_test(e[:, j], theta[:, j]) for j in range(6)]
        white = leftover.noise_sd(tau)
        rest = beyond_own_angle(tau, theta)
        slow = np.sqrt(np.maximum(rest.var(axis=0) - white**2, 0.0))
        joints = {k: verdict_joints(c["data"], c["left"], v) for k, v in tests.items()}
        acting = set(effects[0][2] or range(1, 7)) if effects else set()
        named = [s["added"] for s in c["verdict"]["ladder"]]
        label = ", ".join(f"{n} {c['formulations'][i]} on {j or 'all'}"
                          for i, (n, _, j) in enumerate(effects)) or "no effect"
        print(f"\n{seed} {label}; ladder named {named}")
        for j in range(6):
            po, pn = tests["old"][j]["p"], tests["new"][j]["p"]
            if j + 1 in acting or min(po, pn) < 1e-2:
                curve = tau[:, j] - rest[:, j]
                pw = float(np.median([leftover.angle_test(
                    curve + white[j] * rng.standard_normal(len(curve)), theta[:, j])["p"]
                    for _ in range(5)]))
                bend = f"{1e3 * c['bends'][j]:.3f}" if c["bends"] is not None else "  -  "
                print(f"  joint {j + 1}: {bend} | "
                      f"{1e3 * np.sqrt(tests['old'][j]['explained_var']):.3f} | "
                      f"{1e3 * slow[j]:.3f} | {po:.1e}{'*' if po <= LEVEL else ' '} | "
                      f"{pn:.1e}{'*' if pn <= LEVEL else ' '} | "
                      f"{pw:.1e}{'*' if pw <= LEVEL else ' '}")
        for k in tests:
            flagged = {j + 1 for j in range(6) if tests[k][j]["p"] <= LEVEL}
            false[k] += len(flagged - acting)
            false_verdict[k] += len(set(joints[k]) - acting)
        print(f"  verdict joints old {joints['old']}, new {joints['new']}")
    print(f"\njoints the effect does not act on: passing the angle test old {false['old']}, "
          f"new {false['new']}; in the verdict old {false_verdict['old']}, "
          f"new {false_verdict['new']}")


def white_run(design):
    """A run without effects (seed 4116) and its white leftover: the log's data, the leftover
    (FS units), the angles, the torque map and angle Jacobian, and the leftover's torques."""
    c = run(design, 4116, [])
    data, left = c["data"], c["left"]
    theta = data.theta
    return (data, left, theta, sensitivity.torque_map(data.params, theta),
            sensitivity.angle_jacobian(data.params, theta), data.joint_torque_of(left * data.fs))


def study_white(design) -> None:
    data, left, theta, g, jac, base = white_run(design)
    rng = np.random.default_rng(5)
    print("a curve on one joint added to a white leftover: share of 10 phases found "
          "(p <= 1.67e-4), old / new")
    for j in range(6):
        s = (theta[:, j] - theta[:, j].mean()) / theta[:, j].std()
        line = []
        for bend in (0.02, 0.03, 0.05):
            found = np.zeros(2)
            for phase in rng.uniform(0, 2 * np.pi, 10):
                f = np.sin(2.5 * s + phase)
                f -= np.polyval(np.polyfit(s, f, 1), s)
                sig = np.linalg.solve(g, (jac[:, :, j] * f[:, None])[..., None])[..., 0]
                tau = base + sig * bend * 1e-3 / sig[:, j].std()
                e = conditional(tau, theta)
                found += [leftover.angle_test(x[:, j], theta[:, j])["p"] <= LEVEL
                          for x in (tau, e)]
            line.append(f"{bend:.2f} mN*m: {found[0] / 10:.1f} / {found[1] / 10:.1f}")
        print(f"  joint {j + 1}: " + ", ".join(line))
    chol = np.linalg.cholesky(robust_cov(np.diff(left * data.fs, axis=0)))
    pos = data.position_mm / 1e3
    pos -= pos.mean(axis=0)
    draws = 100
    print(f"\nsimulated white noise (the sensor's cross-axis covariance through G^-1), {draws} "
          "draws: share of the joints without a curve of their own at p <= 0.05 / 0.01 / "
          "1.67e-4, old; new (a force on the plate reaches every joint)")
    for kind in ("white", "curve on joint 1", "curve on joint 4", "pose-dependent force"):
        ps = {"old": [], "new": []}
        for _ in range(draws):
            tau = np.linalg.solve(g, (rng.standard_normal((len(g), 6)) @ chol.T)[..., None])[..., 0]
            carrier = []
            if kind.startswith("curve"):
                k = int(kind[-1]) - 1
                s = (theta[:, k] - theta[:, k].mean()) / theta[:, k].std()
                tau[:, k] += 3 * tau[:, k].std() * np.sin(2.0 * s + rng.uniform(0, 2 * np.pi))
                carrier = [k]
            elif kind.startswith("pose"):
                a = rng.standard_normal((3, 3)) / pos.std()
                force = np.zeros((len(g), 6))
                force[:, :3] = (pos @ a.T + pos**2 @ a / pos.std()) * 2 * np.sqrt(
                    np.diag(chol @ chol.T)[:3])
                tau += np.linalg.solve(g, force[..., None])[..., 0]
            for k, x in (("old", tau), ("new", conditional(tau, theta))):
                ps[k] += [leftover.angle_test(x[:, j], theta[:, j])["p"]
                          for j in range(6) if j not in carrier]
        print(f"  {kind}: " + "; ".join(
            f"{k} " + " / ".join(f"{np.mean(np.array(v) <= a):.3f}" for a in (0.05, 0.01, LEVEL))
            for k, v in ps.items()))


def nuisance_basis(kind: str, theta: np.ndarray, j: int, torque_of=None,
                   position=None) -> np.ndarray:
    """Columns that explain joint j's leftover without its own angle alone (see ``nuisance``)."""
    z = (theta - theta.mean(axis=0)) / theta.std(axis=0)
    others = np.delete(z, j, axis=1)
    if kind == "plate":
        p = (position - position.mean(axis=0)) / position.std(axis=0)
        cols = []
        for axis in range(6):
            for m in (np.ones(len(p)), *p.T):
                w = np.zeros((len(p), 6))
                w[:, axis] = m
                cols.append(torque_of(w)[:, j])
        return np.stack(cols, axis=1)
    first = 0 if kind == "others+cross" else 1
    iu = np.triu_indices(6)
    pairs = [(a, b) for a, b in zip(*iu) if (a, b) != (j, j)
             and (first == 0 or j not in (a, b))]
    return np.hstack([others, np.stack([z[:, a] * z[:, b] for a, b in pairs], axis=1)])


def beyond_nuisance_test(tau: np.ndarray, angle: np.ndarray, nuisance: np.ndarray,
                         folds: int = leftover.ANGLE_FOLDS,
                         degree: int = leftover.ANGLE_DEGREE) -> dict:
    """``leftover.angle_test`` scored against a nuisance: per held-out stretch, the gain of the
    fit on [own-angle polynomial, nuisance] over the fit on [constant, nuisance], both on the
    other stretches (held-out values clipped to their range, as the verdict's test does)."""
    n = len(tau)
    s = (angle - angle.mean()) / (angle.std() or 1.0)
    full = np.hstack([np.stack([s**k for k in range(degree + 1)], axis=1), nuisance])
    null = [0] + list(range(degree + 1, full.shape[1]))
    bounds = np.linspace(0, n, folds + 1).astype(int)
    parts = [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]
    grams = np.stack([full[q].T @ full[q] for q in parts])
    moments = np.stack([full[q].T @ tau[q] for q in parts])
    gains = np.empty(folds)
    for k, q in enumerate(parts):
        gram, moment = grams.sum(0) - grams[k], moments.sum(0) - moments[k]
        coef = np.linalg.lstsq(gram, moment, rcond=None)[0]
        coef_null = np.linalg.lstsq(gram[np.ix_(null, null)], moment[null], rcond=None)[0]
        train = np.ones(n, bool)
        train[q] = False
        lo, hi = full[train].min(axis=0), full[train].max(axis=0)
        held_s = np.clip(s[q], s[train].min(), s[train].max())
        held = np.hstack([np.stack([held_s**d for d in range(degree + 1)], axis=1),
                          np.clip(nuisance[q], lo[degree + 1:], hi[degree + 1:])])
        gains[k] = (np.sum((tau[q] - held[:, null] @ coef_null) ** 2)
                    - np.sum((tau[q] - held @ coef) ** 2))
    sd = gains.std(ddof=1)
    t = float(gains.mean() / (sd / np.sqrt(folds))) if sd > 0 else 0.0
    wins = int(np.sum(gains > 0))
    p_sign = float(sum(math.comb(folds, k) for k in range(wins, folds + 1))) / 2.0**folds
    return {"explained_var": max(float(gains.sum()) / n, 0.0), "t": t, "wins": wins,
            "p": min(1.0, 2.0 * min(leftover.student_t_sf(t, folds - 1), p_sign))}


NUISANCES = ("others", "others+cross", "plate")


def study_nuisance(design, seeds=None, withhold=()) -> None:
    print("per run; per joint (+: the effect acts on it): p old | p with each nuisance "
          f"({', '.join(NUISANCES)}); * <= 1.67e-4")
    kinds = ("old",) + NUISANCES
    false = dict.fromkeys(kinds, 0)
    false_verdict = dict.fromkeys(kinds, 0)
    found = dict.fromkeys(kinds, 0)
    right = dict.fromkeys(kinds, 0)
    acting_total = runs_total = 0
    for seed, effects in RUNS:
        if seeds and seed not in seeds:
            continue
        c = run(design, seed, effects, withhold)
        tau, theta, data = c["tau"], c["theta"], c["data"]
        idx = np.arange(0, len(data), max(1, len(data) // leftover.SHAPE_SAMPLES))
        tests = {"old": [leftover.angle_test(tau[:, j], theta[:, j]) for j in range(6)]}
        for kind in NUISANCES:
            tests[kind] = [beyond_nuisance_test(tau[:, j], theta[:, j], nuisance_basis(
                kind, theta, j, lambda w: data.joint_torque_of(w, idx),
                data.position_mm[idx])) for j in range(6)]
        verdicts = {k: verdict_with(data, c["left"], v) for k, v in tests.items()}
        joints = {k: v["joints"] for k, v in verdicts.items()}
        acting = set(effects[0][2] or range(1, 7)) if effects else set()
        per_joint = bool(effects) and effects[0][2] is not None
        named = [s["added"] for s in c["verdict"]["ladder"]]
        label = ", ".join(f"{n} on {j or 'all'}" for n, _, j in effects) or "no effect"
        print(f"\n{seed} {label}; ladder {named}")
        for j in range(6):
            ps = [tests[k][j]["p"] for k in kinds]
            if j + 1 in acting or min(ps) < 1e-2:
                print(f"  joint {j + 1}{'+' if j + 1 in acting else ' '} " + " | ".join(
                    f"{p:.0e}{'*' if p <= LEVEL else ' '}" for p in ps))
        for k in kinds:
            flagged = {j + 1 for j in range(6) if tests[k][j]["p"] <= LEVEL}
            false[k] += len(flagged - acting)
            false_verdict[k] += len(set(joints[k]) - acting)
            if per_joint:
                found[k] += len(flagged & acting)
                right[k] += set(joints[k]) == acting
        if per_joint:
            acting_total += len(acting)
            runs_total += 1
        print("  verdict joints " + ", ".join(f"{k} {joints[k]}" for k in kinds))
        print("  verdict shape " + ", ".join(f"{k} {verdicts[k]['shape']}" for k in kinds))
    print(f"\nper-joint effects: of {acting_total} joints, passing the angle test "
          + ", ".join(f"{k} {found[k]}" for k in kinds)
          + f"; of {runs_total} runs, verdict joints exactly right "
          + ", ".join(f"{k} {right[k]}" for k in kinds))
    print("joints the effect does not act on, passing: "
          + ", ".join(f"{k} {false[k]}" for k in kinds)
          + "; in the verdict: " + ", ".join(f"{k} {false_verdict[k]}" for k in kinds))


def study_nuisance_sim(design, draws: int = 40) -> None:
    data, left, theta, g, jac, base = white_run(design)

    def torque_of(w):
        return np.linalg.solve(g, w[..., None])[..., 0]
    pos = data.position_mm / 1e3
    pos = pos - pos.mean(axis=0)
    bases = {k: [nuisance_basis(k, theta, j, torque_of, pos) for j in range(6)]
             for k in NUISANCES}
    kinds = ("old",) + NUISANCES

    def test(kind, tau, j):
        if kind == "old":
            return leftover.angle_test(tau[:, j], theta[:, j])
        return beyond_nuisance_test(tau[:, j], theta[:, j], bases[kind][j])

    def pose_force(rng, scale):
        a = rng.standard_normal((3, 3)) / pos.std()
        force = np.zeros((len(g), 6))
        force[:, :3] = (pos @ a.T + pos**2 @ a / pos.std()) * scale
        return torque_of(force)
    rng = np.random.default_rng(5)
    print("a curve on one joint added to the white leftover of a run without effects: share "
          "of 10 phases found (p <= 1.67e-4) and the median held-out angle fit (mN*m), "
          + " / ".join(kinds))
    for slow in (0.0, 0.1, 0.2):
        for j in range(3 if slow else 6):
            s = (theta[:, j] - theta[:, j].mean()) / theta[:, j].std()
            line = []
            for bend in (0.03, 0.05):
                hit = {k: [] for k in kinds}
                for phase in rng.uniform(0, 2 * np.pi, 10):
                    f = np.sin(2.5 * s + phase)
                    f -= np.polyval(np.polyfit(s, f, 1), s)
                    sig = torque_of(jac[:, :, j] * f[:, None])
                    tau = base + sig * bend * 1e-3 / sig[:, j].std()
                    if slow:    # a force on the plate, quadratic in its position
                        extra = pose_force(rng, 1.0)
                        tau = tau + extra * slow * 1e-3 / extra[:, j].std()
                    for k in kinds:
                        r = test(k, tau, j)
                        hit[k].append((r["p"] <= LEVEL, 1e3 * np.sqrt(r["explained_var"])))
                line.append(f"{bend:.2f} mN*m: " + " / ".join(
                    f"{np.mean([h for h, _ in v]):.1f} ({np.median([e for _, e in v]):.3f})"
                    for v in hit.values()))
            print(f"  joint {j + 1}, slow part {slow:.1f} mN*m: " + "; ".join(line))
    chol = np.linalg.cholesky(robust_cov(np.diff(left * data.fs, axis=0)))
    sd_axes = np.sqrt(np.diag(chol @ chol.T))
    print(f"\n{draws} draws of simulated noise (the sensor's cross-axis covariance through "
          "G^-1): share of the joints without a curve of their own at p <= 0.05 / 0.01 / "
          "1.67e-4, and the share of stretches that gain, " + " ; ".join(kinds))
    for kind in ("white", "correlated in time", "curve on joint 1", "curve on joint 5",
                 "pose-dependent force"):
        ps = {k: [] for k in kinds}
        wins = {k: [] for k in kinds}
        for _ in range(draws):
            e = rng.standard_normal((len(g), 6)) @ chol.T
            if kind == "correlated in time":    # white plus an AR(1) of 4 s
                ar = np.empty_like(e)
                ar[0] = e[0]
                for i in range(1, len(e)):
                    ar[i] = 0.995 * ar[i - 1] + 0.0999 * e[i]
                e = e + 3 * ar
            tau = torque_of(e)
            carrier = []
            if kind.startswith("curve"):
                k = int(kind[-1]) - 1
                s = (theta[:, k] - theta[:, k].mean()) / theta[:, k].std()
                sig = torque_of(jac[:, :, k] * np.sin(2.5 * s + rng.uniform(0, 2 * np.pi))[:, None])
                tau += sig * 3 * tau[:, k].std() / sig[:, k].std()
                carrier = [k]
            elif kind.startswith("pose"):
                tau += pose_force(rng, 2 * sd_axes[:3])
            for k in kinds:
                for j in set(range(6)) - set(carrier):
                    r = test(k, tau, j)
                    ps[k].append(r["p"])
                    wins[k].append(r["wins"] / leftover.ANGLE_FOLDS)
        print(f"  {kind}: " + "; ".join(
            f"{k} " + " / ".join(f"{np.mean(np.array(v) <= a):.3f}" for a in (0.05, 0.01, LEVEL))
            + f" ({np.mean(wins[k]):.2f})" for k, v in ps.items()))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", choices=("noise", "runs", "white", "all", "nuisance",
                                            "nuisance-sim"), default="all",
                        help="all: noise, white and runs")
    parser.add_argument("--seeds", type=int, nargs="+", help="runs: only these of its seeds")
    parser.add_argument("--withhold", nargs="+", default=[], choices=[t.name for t in TERMS],
                        help="runs: families withheld beside the three newest")
    args = parser.parse_args()
    design = load_checked(DEFAULT_DESIGN)    # the shipped design: the twin's runs
    studies = (("noise", study_noise), ("white", study_white),
               ("runs", lambda d: study_runs(d, args.seeds, args.withhold)),
               ("nuisance", lambda d: study_nuisance(d, args.seeds, args.withhold)),
               ("nuisance-sim", study_nuisance_sim))
    for name, study in studies:
        if args.study == name or (args.study == "all" and not name.startswith("nuisance")):
            print(f"== {name}")
            study(design)
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
