"""What is left after the ladder: its size against the noise floor, whether it is structured or
white, and where it lives (per joint, as a joint torque against the joint angle, with shape
tests; and in Cartesian space).

The noise floor is estimated from the residual itself: white noise doubles its variance in a
first difference, while slow, structured parts hardly change from one sample to the next (the
median absolute difference, so that rare jumps do not count). A leftover whose variance is at
least ``STRUCTURED_EXCESS`` times that floor on some axis is *structured*: something the
families do not describe is still there.

Shape tests, per joint j, on the leftover expressed as the joint torque that would explain it
(tau = G^-1 r) against the joint's own angle and motion; each test reports the share of the
joint's structured leftover variance its basis explains (least squares, many samples, a few
parameters):

* ``odd polynomial``: theta, theta |theta|, theta^3 (a spring rate that changes with the
  deflection);
* ``even polynomial``: 1, theta^2, theta^4 (an asymmetric spring, a load-dependent offset);
* ``periodic in the angle``: sines and cosines of 3..8 times the angle beyond a cubic (an
  error repeating over the shaft turn faster than the joint range);
* ``direction-dependent``: the direction of motion and play states (history);
* ``coupled across joints``: the other joints' angles beyond the joint's own cubic.

And once for the mechanism: ``pose-dependent in Cartesian space``, the share of the leftover
force (in {B}) explained by an affine-plus-quadratic function of the plate's position (a
harness or cable pulling on the plate).

A leftover can be structured while far smaller than the noise: an error that is a function
of one joint's angle (an encoder's error over its shaft turn, what is left of it once a
spring-rate and an offset term took its straight-line part) is coherent over the whole log,
noise is not. Per joint, a smooth function of the joint's own angle (a polynomial up to
``ANGLE_DEGREE``) is fitted on all but one of ``ANGLE_FOLDS`` contiguous stretches of the log
and scored on the one left out; white noise of any level gives the held-out fits no gain on
average, so the folds' gains are tested against zero (Student t, one-sided; and by their
signs, which a large structure passes however unevenly the stretches sweep the angle), at
``ANGLE_ALPHA`` over the six joints (Holm's step-down) and the two tests. Contiguous
stretches keep the test honest on noise that is correlated from sample to sample and on a
leftover that changes from one held-out fold of the ladder to the next: neither is a function
of the angle.
"""
from __future__ import annotations

import math

import numpy as np

from delta6.core.model import rotation
from delta6.diagnosis.data import GapData

STRUCTURED_EXCESS = 1.5
#: A joint "carries" the leftover when its structured torque variance is at least this share
#: of the largest joint's.
JOINT_SHARE = 0.25
#: A shape is named when its basis explains at least this share of the structured leftover.
SHAPE_SHARE = 0.5
#: Samples used for the shape fits (spread over the log; enough for a few parameters).
SHAPE_SAMPLES = 60_000
#: The held-out angle test: contiguous stretches, polynomial degree in the joint's own angle,
#: and the false-alarm rate over the six joints together (a white leftover is called
#: angle-structured on at most this share of runs). 40 stretches (10 s each in a 400 s log):
#: twice the 20 until round 14, whose t and sign tests lacked the power to place an encoder's
#: periodic error on the second of its two joints (p 0.0004-0.002 against 2e-4; 1e-6 with 40).
ANGLE_FOLDS = 40
ANGLE_DEGREE = 5
ANGLE_ALPHA = 1e-3


def noise_sd(values: np.ndarray, scale=1.0) -> np.ndarray:
    """White-noise standard deviation per column of ``values / scale``, from the median
    absolute first difference (in place on one difference array: long logs)."""
    d = np.diff(values, axis=0)
    d /= scale
    d -= np.median(d, axis=0)
    np.abs(d, out=d)
    mad = np.median(d, axis=0, overwrite_input=True)
    return 1.4826 * mad / np.sqrt(2.0)


def student_t_sf(t: float, dof: int) -> float:
    """P(T > t) for Student's t with an integer number of degrees of freedom (the closed form
    of Abramowitz and Stegun 26.7.3-4: a finite series in the cosine of atan(t / sqrt(dof)))."""
    if dof < 1:
        raise ValueError("dof must be at least 1")
    theta = np.arctan(abs(t) / np.sqrt(dof))
    c2, s = np.cos(theta) ** 2, np.sin(theta)
    if dof % 2:
        term, series = np.cos(theta), 0.0
        for k in range(1, (dof - 1) // 2 + 1):
            series += term
            term *= c2 * (2 * k) / (2 * k + 1)
        inside = 2.0 / np.pi * (theta + s * series) if dof > 1 else 2.0 / np.pi * theta
    else:
        term, series = 1.0, 0.0
        for k in range(1, dof // 2 + 1):
            series += term
            term *= c2 * (2 * k - 1) / (2 * k)
        inside = s * series
    tail = min(max(0.5 * (1.0 - float(inside)), 0.0), 0.5)    # rounding, far out
    return tail if t >= 0 else 1.0 - tail


def angle_test(tau: np.ndarray, angle: np.ndarray, folds: int = ANGLE_FOLDS,
               degree: int = ANGLE_DEGREE) -> dict:
    """Held-out test of whether ``tau`` (n,) is a smooth function of ``angle`` (n,): a
    polynomial up to ``degree`` in the standardised angle, fitted on all but one of ``folds``
    contiguous stretches and scored on the stretch left out. Returns the held-out explained
    variance (the mean gain per sample over a constant fitted the same way, at least 0), the
    one-sided t statistic of the stretches' gains against zero, how many stretches gain, and
    the p-value of the two tests together."""
    n = len(tau)
    spread = angle.std()
    s = (angle - angle.mean()) / (spread if spread > 0 else 1.0)
    basis = np.stack([s**k for k in range(degree + 1)], axis=1)
    bounds = np.linspace(0, n, folds + 1).astype(int)
    grams = np.stack([basis[a:b].T @ basis[a:b] for a, b in zip(bounds[:-1], bounds[1:])])
    moments = np.stack([basis[a:b].T @ tau[a:b] for a, b in zip(bounds[:-1], bounds[1:])])
    gains = np.empty(folds)
    for k, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
        coef, *_ = np.linalg.lstsq(grams.sum(0) - grams[k], moments.sum(0) - moments[k],
                                   rcond=None)
        mean = (tau[:a].sum() + tau[b:].sum()) / (n - (b - a))
        # A stretch that sweeps angles the others never reach is scored with the fit held at
        # the edge of what it was fitted on: a polynomial of this degree extrapolated would
        # cost the stretch more than any structure gains elsewhere.
        lo = min(s[:a].min(initial=np.inf), s[b:].min(initial=np.inf))
        hi = max(s[:a].max(initial=-np.inf), s[b:].max(initial=-np.inf))
        held = np.clip(s[a:b], lo, hi) if lo <= hi else s[a:b]
        fitted = np.stack([held**d for d in range(degree + 1)], axis=1) @ coef
        gains[k] = np.sum((tau[a:b] - mean) ** 2) - np.sum((tau[a:b] - fitted) ** 2)
    sd = gains.std(ddof=1)
    t = float(gains.mean() / (sd / np.sqrt(folds))) if sd > 0 else 0.0
    # The t test's statistic stops growing with the structure's size once the stretches'
    # gains differ by how much of the angle's range each one sweeps; a sign test does not
    # care: without structure, a stretch gains with probability at most one half (the fit
    # elsewhere is independent of the stretch's noise, and costs its own overfit).
    wins = int(np.sum(gains > 0))
    p_sign = float(sum(math.comb(folds, k) for k in range(wins, folds + 1))) / 2.0**folds
    return {"explained_var": max(float(gains.sum()) / n, 0.0), "t": t, "wins": wins,
            # Bonferroni over the two tests: the level holds for their union.
            "p": min(1.0, 2.0 * min(student_t_sf(t, folds - 1), p_sign))}


def holm(p: list[float], alpha: float) -> list[bool]:
    """Which of the hypotheses with p-values ``p`` Holm's step-down rejects at family-wise
    level ``alpha``: the smallest p against alpha / m, the next against alpha / (m - 1), ...,
    stopping at the first that fails. The same false-alarm rate as Bonferroni (alpha / m for
    all), more power where more than one holds: an effect on two joints, the second weaker."""
    reject = [False] * len(p)
    for rank, i in enumerate(np.argsort(p, kind="stable")):
        if not p[i] <= alpha / (len(p) - rank):
            break
        reject[i] = True
    return reject


def _share(target: np.ndarray, basis: np.ndarray, structured_var: float) -> float:
    """Share of ``structured_var`` the least-squares fit of ``target`` on ``basis`` explains."""
    if structured_var <= 0:
        return 0.0
    coef, *_ = np.linalg.lstsq(basis, target, rcond=None)
    explained = np.var(basis @ coef) if basis.shape[1] else 0.0
    return float(np.clip(explained / structured_var, 0.0, 1.0))


def _own(theta: np.ndarray) -> np.ndarray:
    return np.stack([np.ones_like(theta), theta, theta**2, theta**3], axis=1)


def _joint_shapes(tau: np.ndarray, theta: np.ndarray, j: int, direction: np.ndarray,
                  structured_var: float, in_angle: bool = False) -> dict:
    """Each shape's share of the joint's structured leftover, and the shape named. With
    ``in_angle`` (the held-out test found a function of the joint's own angle), a leftover
    that the joint's own cubic explains though neither its odd nor its even part does alone
    (what is left of a periodic error once its straight-line part is gone has both) is
    named by the larger part."""
    th = theta[:, j]
    centred = tau - tau.mean()
    own = _own(th)
    base_own = _share(centred, own, structured_var)
    periodic = np.stack([f(h * th) for h in range(3, 9) for f in (np.sin, np.cos)], axis=1)
    others = np.delete(theta, j, axis=1)
    shares = {
        "odd polynomial": _share(centred, np.stack([th, th * np.abs(th), th**3], axis=1),
                                 structured_var),
        "even polynomial": _share(centred, np.stack([np.ones_like(th), th**2, th**4], axis=1),
                                  structured_var),
        "periodic in the angle": max(0.0, _share(centred, np.hstack([own, periodic]),
                                                 structured_var) - base_own),
        "direction-dependent": _share(centred, np.hstack([np.ones((len(th), 1)),
                                                          direction]), structured_var),
        "coupled across joints": max(0.0, _share(centred, np.hstack([own, others, others**2]),
                                                 structured_var) - base_own),
    }
    best = max(shares, key=shares.get)
    if shares[best] < SHAPE_SHARE:
        best = None
        if in_angle and base_own >= SHAPE_SHARE:
            best = max(("odd polynomial", "even polynomial"), key=shares.get)
    return {"shares": shares, "best": best}


def analyse(data: GapData, leftover_fs: np.ndarray) -> dict:
    """The verdict on the leftover ``leftover_fs`` (n, 6), FS-normalised held-out residual
    after the ladder."""
    noise = noise_sd(data.residual, data.fs)
    rms = np.sqrt(np.mean(leftover_fs**2, axis=0))
    excess = rms**2 / np.maximum(noise**2, 1e-300)
    structured_share = np.clip(1.0 - 1.0 / np.maximum(excess, 1e-12), 0.0, 1.0)
    structured = bool(np.any(excess >= STRUCTURED_EXCESS))
    out = {
        "rms_pct": (100 * rms).tolist(),
        "noise_rms_pct": (100 * noise).tolist(),
        "excess_over_noise": excess.tolist(),
        "structured_share": structured_share.tolist(),
        "structured": structured,
        "joints": [], "per_joint": [], "cartesian": None, "shape": None,
    }
    step = max(1, len(data) // SHAPE_SAMPLES)
    idx = np.arange(0, len(data), step)
    wrench_err = leftover_fs[idx] * data.fs
    tau = data.joint_torque_of(wrench_err, idx)
    # Torque noise per joint from the whole-rate signal (the subsample would alias it).
    tau_noise = noise_sd(data.joint_torque_of(leftover_fs[:min(len(data), SHAPE_SAMPLES)]
                                              * data.fs, slice(0, min(len(data),
                                                                      SHAPE_SAMPLES))))
    var = tau.var(axis=0)
    structured_var = np.maximum(var - tau_noise**2, 0.0)
    theta = data.theta[idx]
    direction = np.concatenate([np.tanh(data.smooth_velocity[idx] / 0.01),
                                data.play_state((0.01, 0.05))[idx].reshape(len(idx), -1)],
                               axis=1)
    rows = []
    angles = [angle_test(tau[:, j], theta[:, j]) for j in range(6)]
    # Over the six joints at the whole verdict's false-alarm rate.
    in_angle = holm([a["p"] for a in angles], ANGLE_ALPHA)
    for j, angle in enumerate(angles):
        row = {"joint": j + 1, "leftover_rms_nm": float(np.sqrt(var[j])),
               "noise_rms_nm": float(tau_noise[j]),
               "structured_rms_nm": float(np.sqrt(structured_var[j])),
               "angle_rms_nm": float(np.sqrt(angle["explained_var"])),
               "angle_t": angle["t"], "angle_p": angle["p"],
               "angle_structured": in_angle[j]}
        row["structured"] = bool(var[j] >= STRUCTURED_EXCESS * tau_noise[j] ** 2)
        # A structure below the noise floor is measured by what its held-out fit explains:
        # the variance above the floor is then mostly the floor estimate's own error.
        amount = angle["explained_var"] if row["angle_structured"] and not row["structured"] \
            else structured_var[j]
        row.update(_joint_shapes(tau[:, j], theta, j, direction, amount,
                                 in_angle=row["angle_structured"]))
        rows.append((row, amount))
        out["per_joint"].append(row)
    out["structured"] = structured = structured or any(r["angle_structured"] for r, _ in rows)
    out["joints"] = _carrying(rows) if structured else []
    out["cartesian"] = _cartesian(data, wrench_err, idx)
    out["shape"] = _verdict_shape(out) if structured else None
    return out


def _carrying(rows: list[tuple[dict, float]]) -> list[int]:
    """The joints that carry the leftover: those whose structured part is at least
    ``JOINT_SHARE`` of the largest one's. When some joint's leftover is a significant function
    of its own angle, among those and the joints above the noise floor whose structure has a
    shape: a joint above the floor with no shape is then structured in time, not in the
    mechanism's state (the ladder's parameters changing from one held-out fold to the next),
    and its size says nothing about where the unknown effect is."""
    pool = [(r, a) for r, a in rows if r["structured"]]
    top = max((a for _, a in rows), default=0.0)
    if any(r["angle_structured"] for r, _ in rows):
        pool = [(r, a) for r, a in rows if (r["structured"] and r["best"])
                or r["angle_structured"]]
        top = max(a for _, a in pool)
    return [r["joint"] for r, a in pool if top > 0 and a >= JOINT_SHARE * top]


def _cartesian(data: GapData, wrench_err: np.ndarray, idx: np.ndarray) -> dict:
    """Share of the leftover force, turned into {B}, that an affine-plus-quadratic function of
    the plate position explains."""
    force_b = np.einsum("nij,nj->ni", rotation(data.theta[idx, 3:]), wrench_err[:, :3])
    pos = data.position_mm[idx] / 1e3
    pos = pos - pos.mean(axis=0)
    x, y, z = pos.T
    basis = np.stack([np.ones_like(x), x, y, z, x * x, y * y, z * z, x * y, x * z, y * z],
                     axis=1)
    # Against the same number of parameters separable per joint (each of joints 1..3 on its
    # own, up to its cube): a joint-level effect is explained at least as well by that.
    th = data.theta[idx, :3]
    separable = np.hstack([np.ones((len(idx), 1)), th, th**2, th**3])
    noise = noise_sd(force_b)
    total = float(np.sum(np.maximum(force_b.var(axis=0) - noise**2, 0.0)))
    if total <= 0:
        return {"share": 0.0, "separable_share": 0.0}
    centred = force_b - force_b.mean(axis=0)
    shares = []
    for b in (basis, separable):
        coef, *_ = np.linalg.lstsq(b, centred, rcond=None)
        shares.append(float(np.clip(np.sum(np.var(b @ coef, axis=0)) / total, 0.0, 1.0)))
    return {"share": shares[0], "separable_share": shares[1]}


def _verdict_shape(out: dict) -> str | None:
    """One shape for the leftover: pose-dependent in Cartesian space when a function of the
    plate's position explains the leftover force and some joint's structured leftover depends
    on the other joints' angles (a force on the plate reaches every joint; one clamped off
    the plate's centre turns the gimbal with a moment that follows the plate's position, even
    when the proximal joints' share looks like a rate error of their own); else the most
    common shape of the joints that carry it."""
    joints = out["joints"]
    shapes = [out["per_joint"][j - 1]["best"] for j in joints]
    cart = out["cartesian"]
    coupled = any(row["structured"] and row["best"] == "coupled across joints"
                  for row in out["per_joint"])
    if cart["share"] >= SHAPE_SHARE and cart["share"] >= cart["separable_share"] and coupled:
        return "pose-dependent in Cartesian space"
    shapes = [s for s in shapes if s]
    if not shapes:
        return "unresolved"
    return max(set(shapes), key=shapes.count)
