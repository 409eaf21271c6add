"""The diagnosis on harder logs: one axis at a time (interleaved folds, a ladder that never
gets worse), mixes of direction-dependent effects (backlash's own signature, group verdicts),
implausible fits, effects the vocabulary lacks (the leftover verdict), and the excitation
report."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from delta6 import twin
from delta6.diagnosis import blas, ladder, selection, terms, verdicts
from delta6.diagnosis.data import GapData
from delta6.diagnosis.run import diagnose
from delta6.diagnosis.terms import TERMS
from delta6.link.logfile import LogData
from delta6.twin.pushes import AxisPushes
from delta6.twin.streams import stream

TERM_BY_NAME = {t.name: t for t in TERMS}
DURATION_S = 240.0


def run(design, effects, seed, path=None, terms=None, duration=DURATION_S):
    r = twin.simulate(design, effects, duration_s=duration, rate_hz=50.0, seed=seed,
                      record_temp=True, path=path)
    log = LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c)
    return r, diagnose(log, design, seed=0, terms=terms)


def never_worse(verdict):
    before = np.asarray(verdict["baseline_heldout_p99_pct"])
    for step in verdict["ladder"]:
        now = np.asarray(step["heldout_p99_pct"])
        assert np.all(now <= before), (now, before)
        before = now


@given(st.integers(36, 120), st.integers(3, 7))
def test_every_folds_training_blocks_reach_every_sixth_of_the_log(n_blocks, n_folds):
    folds = selection.make_folds(n_blocks, n_folds)
    assert sorted(np.concatenate(folds).tolist()) == list(range(n_blocks))
    if n_blocks < n_folds * selection.RUN_BLOCKS * 2:
        return
    problem = selection.Problem(y=None, x=None, slices={}, terms={},
                                bounds=np.arange(n_blocks + 1), gram=np.zeros((n_blocks, 0, 0)),
                                xty=np.zeros((n_blocks, 0)), yty=np.zeros(n_blocks),
                                folds=folds)
    sixths = np.array_split(np.arange(n_blocks), 6)
    for fold in folds:
        train = set(selection.train_blocks(problem, fold).tolist())
        assert not train & set(fold.tolist())
        assert all(train & set(s.tolist()) for s in sixths)


@given(arrays(float, (300, 6), elements=st.floats(-1, 1)),
       st.lists(arrays(float, (300, 6), elements=st.floats(-1, 1)), min_size=1, max_size=4))
def test_a_damped_ladder_never_gets_worse_on_any_axis(y, preds):
    start = ladder.baseline_p99(y)
    weights, p99s, final, sses, refits = ladder.monotone(y, preds)
    assert all(np.all((0.0 <= a) & (a <= 1.0)) and a.shape == (6,) for a in weights)
    # The reported p99s never rise, not even by a rounding, from the reported start on; an
    # axis a step leaves alone reports exactly the p99 of the step before.
    before = start
    for a, reported in zip(weights, p99s):
        assert np.all(reported <= before)
        assert np.array_equal(reported[a == 0.0], before[a == 0.0])
        before = reported
    # Rebuild the per-axis blend from the weights: the reported figures are that model's.
    blended = np.zeros_like(y)
    for a, pred, reported, sse in zip(weights, preds, p99s, sses):
        blended = blended + a * (pred - blended)
        assert np.allclose(ladder.p99(100 * (y - blended)), reported)
        assert np.isclose(((y - blended) ** 2).sum(), sse)
    assert np.allclose(final, blended)
    # Each step's refit, undamped, is reported too: what one set of parameters gives.
    for pred, refit in zip(preds, refits):
        assert np.allclose(ladder.p99(100 * (y - pred)), refit)


def test_an_axis_a_step_leaves_alone_stays_finite_whatever_the_step_predicts_there():
    """A prediction that overflowed on an axis the step does not take leaves that axis
    exactly as the step before (0 x inf would be NaN in the report's JSON)."""
    y = np.random.default_rng(5).normal(size=(500, 6))
    pred = 0.5 * y
    pred[:, 2] = -y[:, 2]                   # worse on that axis: not taken there
    pred[0, 2] = np.inf
    weights, p99s, final, sses, _ = ladder.monotone(y, [pred])
    assert weights[0][2] == 0.0 and np.all(np.isfinite(final)) and np.isfinite(sses[0])
    assert np.all(np.isfinite(p99s[0]))


def test_an_axis_that_a_step_makes_worse_is_left_alone_and_the_others_keep_it():
    """One step halves the error of five axes and doubles the sixth's: the five take it
    whole, the sixth keeps the step before exactly (a common weight would give up the five's
    gain or let the sixth get worse)."""
    rng = np.random.default_rng(3)
    y = rng.normal(size=(2000, 6))
    pred = 0.5 * y
    pred[:, 5] = -y[:, 5]
    weights, p99s, final, _, _ = ladder.monotone(y, [pred])
    assert np.array_equal(weights[0], [1, 1, 1, 1, 1, 0])
    assert np.array_equal(final[:, 5], np.zeros(2000))
    assert np.array_equal(p99s[0][5], ladder.baseline_p99(y)[5])
    assert np.all(p99s[0][:5] < 0.6 * ladder.baseline_p99(y)[:5])


def test_one_axis_at_a_time_names_the_effect_and_never_worsens_an_axis(baseline):
    effect = twin.make_effect("spring_hysteresis", seed=41, formulation="bouc_wen",
                              magnitude=0.9)
    path = AxisPushes(baseline, 300.0, stream(41, "pushes"))
    _, verdict = run(baseline, [effect], 41, path=path, duration=300.0)
    assert verdict["present"][:1] == ["spring_hysteresis"]
    assert verdict["candidates"][0]["score"] > 0.6
    never_worse(verdict)
    report = verdict["excitation"]
    assert set(report["families"]) == {t.name for t in TERMS if t.name != "thermal_drift"} \
        or set(report["families"]) == {t.name for t in TERMS}
    assert min(report["axes"]["training_share_min"]) > 0.2
    # A loop alone needs no play beside it.
    assert not any("backlash" in g["members"] for g in verdict["groups"])


@pytest.fixture(scope="module")
def mixes(baseline):
    with_backlash = [twin.make_effect("backlash", seed=42, formulation="dead_zone",
                                      magnitude=0.9),
                     twin.make_effect("spring_hysteresis", seed=42, magnitude=0.7)]
    without = [twin.make_effect("joint_friction", seed=43, magnitude=0.8),
               twin.make_effect("spring_hysteresis", seed=43, magnitude=0.7)]
    return run(baseline, with_backlash, 42)[1], run(baseline, without, 43)[1]


def test_backlash_is_confirmed_by_its_own_signature_and_only_when_there(mixes):
    with_backlash, without = mixes
    assert with_backlash["signature_tests"]["backlash"]["confirmed"]
    assert "backlash" in with_backlash["present"]
    assert not without["signature_tests"].get("backlash", {"confirmed": False})["confirmed"]
    assert "backlash" not in without["present"]
    assert not any("backlash" in g["members"] for g in without["groups"])
    for v in mixes:
        never_worse(v)


def test_a_play_the_hysteresis_took_up_is_named_with_it_in_the_group_verdict(baseline):
    """One axis at a time, a play of 6-9 mrad beside a hysteresis loop (a development case):
    the loop takes up the play's switch, the held-out error gains nothing from the play and
    its dwell signature does not confirm it; fitted with the model it is a play of several
    counts on most joints, so the verdict says "spring_hysteresis and/or backlash"."""
    from delta6.evaluation.gap_benchmark import Case, _effects
    case = Case(kind="axis", seed=27260034, path="axis",
                effects=["stiffness_mismatch", "spring_hysteresis", "backlash",
                         "thermal_drift", "encoder_periodic_error"],
                magnitudes=[0.786, 0.778, 0.782, 0.818, 0.820])
    path = AxisPushes(baseline, 400.0, stream(case.seed, "pushes"))
    _, verdict = run(baseline, _effects(case), case.seed, path=path, duration=400.0)
    assert "backlash" not in verdict["present"]
    assert not verdict["signature_tests"]["backlash"]["confirmed"]
    (group,) = [g for g in verdict["groups"] if "backlash" in g["members"]]
    assert "spring_hysteresis" in group["members"] and "spring_hysteresis" in verdict["present"]
    assert "and/or backlash" in group["text"]
    beside = group["play_beside"]
    assert len(beside["joints"]) >= verdicts.PLAY_BESIDE_JOINTS
    assert all(beside["play_rad"][j - 1] >= verdicts.PLAY_BESIDE_RAD for j in beside["joints"])
    assert all(p < 0.05 for p in beside["play_rad"])
    # The shrink is predicted with that play taken away, on the joints that show it.
    gone = verdict["beyond_encoders"]["backlash"]
    expected = [beside["play_rad"][j] if j + 1 in beside["joints"] else 0.0 for j in range(6)]
    assert gone["play_rad"] == pytest.approx(expected)
    assert np.mean(gone["heldout_p99_pct"]) < np.mean(verdict["ladder"][-1]["heldout_p99_pct"])
    never_worse(verdict)


def test_a_play_beside_the_hysteresis_joins_its_group_or_makes_one_with_the_loop(baseline):
    r = twin.simulate(baseline, [twin.make_effect("spring_hysteresis", seed=44, magnitude=0.9)],
                      duration_s=120, seed=44)
    data = GapData.from_log(LogData(t=r.t, theta=r.theta, wrench=r.wrench), baseline)
    names = ["spring_hysteresis", "joint_friction", "backlash"]
    problem = selection.build_problem(data, [TERM_BY_NAME[n] for n in names])
    beside = {"play_rad": [0.004] * 6, "joints": [1, 2, 3]}
    chosen = ["spring_hysteresis", "joint_friction"]
    # No verdict yet: the loop and the play, not the friction the selection told apart.
    (made,) = verdicts.join_play(problem, chosen, chosen, [], beside)
    assert made["members"] == ["spring_hysteresis", "backlash"]
    assert made["named_alone"] == ["spring_hysteresis"]
    assert made["play_beside"] is beside and "and/or backlash" in made["text"]
    assert 0.0 < made["share_of_gap"] <= 1.5
    # A verdict there already: the play joins it, and what it said stays.
    other = {"group": "smooth", "members": ["x", "y"]}
    found = {"group": made["group"], "members": ["spring_hysteresis", "joint_friction"],
             "named_alone": ["spring_hysteresis"], "folded": ["joint_friction"],
             "share_of_gap": 0.5, "text": "..."}
    joined = verdicts.join_play(problem, chosen, ["spring_hysteresis"], [found, other], beside)
    assert joined[0] is other
    assert joined[1]["members"] == ["spring_hysteresis", "joint_friction", "backlash"]
    assert joined[1]["folded"] == ["joint_friction"]
    assert joined[1]["named_alone"] == ["spring_hysteresis"]


def test_group_verdict_names_effects_the_log_cannot_tell_apart(baseline):
    r = twin.simulate(baseline, [twin.make_effect("spring_hysteresis", seed=44, magnitude=0.9)],
                      duration_s=120, seed=44)
    data = GapData.from_log(LogData(t=r.t, theta=r.theta, wrench=r.wrench), baseline)
    terms = [TERM_BY_NAME["spring_hysteresis"], TERM_BY_NAME["joint_friction"],
             TERM_BY_NAME["stiffness_mismatch"]]
    problem = selection.build_problem(data, terms)
    base = selection.heldout_block_sse(problem, [])
    info = {"forward": ["spring_hysteresis", "joint_friction"], "dropped": ["joint_friction"],
            "base": base}
    found = verdicts.groups(problem, ["spring_hysteresis"], info)
    assert len(found) == 1
    g = found[0]
    assert g["members"] == ["spring_hysteresis", "joint_friction"]
    assert g["group"] == "direction-dependent joint torque"
    assert 0.5 < g["share_of_gap"] <= 1.0
    assert "spring_hysteresis and/or joint_friction" in g["text"]
    # Nothing dropped, or members of no common group: no group verdict.
    assert verdicts.groups(problem, ["spring_hysteresis"],
                           {**info, "dropped": []}) == []
    assert verdicts.groups(problem, ["spring_hysteresis"],
                           {**info, "forward": ["spring_hysteresis", "stiffness_mismatch"],
                            "dropped": ["stiffness_mismatch"]}) == []


def test_group_members_carry_what_their_group_carries_for_the_partial_rule(baseline):
    # Hysteresis and friction together: each stands in for the other's part, so each one's
    # own share of the gap is small (under the partial rule's threshold) while together they
    # carry nearly all of it; a family of no group carries its own share.
    from delta6.diagnosis.run import PARTIAL_SHARE, group_shares
    effects = [twin.make_effect("spring_hysteresis", seed=44, magnitude=0.9),
               twin.make_effect("joint_friction", seed=44, magnitude=0.9)]
    r = twin.simulate(baseline, effects, duration_s=120, seed=44)
    data = GapData.from_log(LogData(t=r.t, theta=r.theta, wrench=r.wrench), baseline)
    names = ["spring_hysteresis", "joint_friction", "stiffness_mismatch"]
    problem = selection.build_problem(data, [TERM_BY_NAME[n] for n in names])
    base = selection.heldout_block_sse(problem, []).sum()
    full = selection.heldout_block_sse(problem, names).sum()
    own = {n: (selection.heldout_block_sse(problem, [m for m in names if m != n]).sum()
               - full) / base for n in names}
    carried = group_shares(problem, names, base)
    assert max(own["spring_hysteresis"], own["joint_friction"]) < PARTIAL_SHARE
    assert carried["spring_hysteresis"] == carried["joint_friction"] > 0.8
    assert np.isclose(carried["stiffness_mismatch"], own["stiffness_mismatch"])


def _along_motion(coef, cov=None):
    friction = TERM_BY_NAME["joint_friction"]
    (check,) = friction.sign_checks(coef, cov)
    assert check["quantity"] == "torque_along_motion_nm"
    return check["ratio"]


@given(coulomb=st.floats(5e-4, 8e-3), excess=st.floats(0.0, 1.0),
       stribeck=st.floats(0.005, 0.05), viscous=st.floats(0.0, 5e-3))
def test_a_friction_that_opposes_the_motion_is_plausible(coulomb, excess, stribeck, viscous):
    # The twin's Stribeck curve, fitted on the family's features: whatever its shape (falling
    # from breakaway, so its slope over 0.05..0.5 rad/s may be negative), it never pushes.
    speeds = np.geomspace(1e-3, 1.0, 200)
    curve = coulomb * (1 + excess * np.exp(-(speeds / stribeck) ** 2)) * np.tanh(
        speeds / 0.005) + viscous * speeds
    feats = np.concatenate([terms.speed_features(speeds), np.ones((200, 1))], axis=1)
    per_joint, *_ = np.linalg.lstsq(feats, curve, rcond=None)
    assert _along_motion(np.tile(per_joint, 6)) == 0.0


def test_a_friction_that_pushes_the_joint_along_is_not_friction():
    # A reference 30 ms late makes a viscous term of -k x 30 ms on every joint: at 0.5 rad/s
    # it pushes by 10 mN*m, ten times the tolerance; undetermined, it is not out of bounds.
    width = len(TERM_BY_NAME["joint_friction"].param_names) // 6
    coef = np.zeros(6 * width)
    coef[3::width] = -0.02
    assert _along_motion(coef) == pytest.approx(10.0)
    assert _along_motion(coef, np.eye(6 * width) * 0.02 ** 2) == 0.0
    # Joint by joint: each joint's own coefficients (Coulomb levels, viscous, pre-sliding).
    for j in range(6):
        one = np.zeros(6 * width)
        one[j * width + 3] = -0.02                  # joint j pushes along ...
        assert _along_motion(one) == pytest.approx(10.0)
        one[j * width + 1] = 0.02                   # ... unless its Coulomb friction outweighs
        assert _along_motion(one) == 0.0
        one[((j + 1) % 6) * width + 4] = -0.003     # another joint's memory term pushes
        assert _along_motion(one) == pytest.approx(3.0)


def test_plausibility_flags_fits_out_of_bounds_beyond_their_uncertainty():
    geometry = TERM_BY_NAME["geometry_error"]
    coef = np.zeros(len(geometry.param_names))
    coef[9] = 4.7                                   # lb1: a 4.7 mm assembly error
    checks = {c["quantity"]: c for c in geometry.plausibility(coef)}
    assert checks["length_error_mm"]["ratio"] > 2
    assert checks["angle_error_rad"]["ratio"] == 0
    # Undetermined (a standard error of 2 mm): not out of bounds beyond three of them.
    se = np.full(len(coef), 2.0)
    assert geometry.plausibility(coef, np.diag(se ** 2))[0]["ratio"] == 0
    hysteresis = TERM_BY_NAME["spring_hysteresis"]
    loop = np.zeros(len(hysteresis.param_names))
    loop[:5] = 0.02                                  # joint 1: a 0.1 N*m half-width
    assert hysteresis.plausibility(loop)[0]["ratio"] == pytest.approx(2.0)


def test_an_unknown_effect_leaves_a_structured_leftover_in_the_right_place(baseline):
    effect = twin.make_effect("nonlinear_spring", seed=45, formulation="cubic", magnitude=0.9,
                              joints=[2])
    # The vocabulary before the three newest families (the encoder family's smooth angle
    # errors could express a spring's curvature too).
    newest = ("nonlinear_spring", "encoder_periodic_error", "harness")
    terms = [t for t in TERMS if t.name not in newest]
    _, verdict = run(baseline, [effect], 45, terms=terms)
    left = verdict["unexplained"]["verdict"]
    assert left["structured"] and left["joints"] == [2]
    assert left["shape"] == "odd polynomial"
    assert max(left["excess_over_noise"]) > 1.5
    shares = {s["added"]: s["share_of_gap"] for s in verdict["ladder"]}
    assert all(shares[n] >= 0.3 for n in verdict["present"])
    never_worse(verdict)


def test_a_small_name_another_family_fits_as_well_is_not_named(baseline):
    # An encoder error on joints 1 and 6 the vocabulary lacks (a development case): a thermal
    # drift fitted a quarter of the gap, and an encoder offset fits it as well in its place.
    from delta6.diagnosis.report import verdict_lines
    from delta6.evaluation.gap_benchmark import Case, _effects
    case = Case(kind="unknown", effects=["encoder_periodic_error"], seed=25040052,
                magnitudes=[0.8313764233722027], joints=[[1, 6]])
    newest = ("nonlinear_spring", "encoder_periodic_error", "harness")
    terms = [t for t in TERMS if t.name not in newest]
    _, verdict = run(baseline, _effects(case), case.seed, terms=terms, duration=400.0)
    assert verdict["unexplained"]["verdict"]["structured"]
    (entry,) = [e for e in verdict["stand_ins"] if e["name"] == "thermal_drift"]
    assert entry["stand_ins"] and "thermal_drift" not in entry["stand_ins"]
    assert entry["share_of_gap"] < 0.3
    assert "thermal_drift" not in verdict["present"]
    assert not any("thermal_drift" in g["members"] for g in verdict["groups"])
    ladder = {s["added"]: s for s in verdict["ladder"]}
    assert "thermal_drift" in ladder and not ladder["thermal_drift"]["named"]
    assert all(ladder[n]["share_of_gap"] >= 0.3 for n in verdict["present"])
    assert any(line.startswith("- Not named: thermal_drift carries") and "fits as well" in line
               for line in verdict_lines(verdict))


def test_a_clean_log_leaves_a_white_leftover(baseline):
    _, verdict = run(baseline, [], 46, duration=120.0)
    left = verdict["unexplained"]["verdict"]
    assert verdict["present"] == [] and not left["structured"] and left["joints"] == []
    assert np.all(np.asarray(left["excess_over_noise"]) < 1.5)


def test_blas_is_held_to_one_thread_and_given_back():
    controls = blas._controls()
    before = [get() for get, _ in controls]
    with blas.one_thread():
        assert all(get() == 1 for get, _ in controls)
    assert [get() for get, _ in controls] == before


@pytest.fixture(scope="module")
def clean_log(baseline):
    r = twin.simulate(baseline, [], duration_s=DURATION_S, rate_hz=50.0, seed=47,
                      record_temp=True)
    return LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c)


@pytest.mark.parametrize("share_of_noise, named", [(0.06, False), (0.6, True)])
def test_a_family_is_named_only_above_the_noise_floor(baseline, clean_log, share_of_noise,
                                                      named):
    """The same spring-rate error, injected at a given share of the white noise's squared
    error over the log: held-out scoring finds it either way, but below one axis's worth of
    noise it is not named (nothing tells its cause from noise or an unknown neighbour)."""
    data = GapData.from_log(clean_log, baseline)
    cols = TERM_BY_NAME["stiffness_mismatch"].columns(data) / data.fs[None, :, None]
    shape = cols @ np.array([1.0, -0.5, 0.8, 0.0, 0.0, 0.0])
    floor = 6 * len(data) * selection.noise_variance(data.residual, data.fs)
    scale = np.sqrt(share_of_noise * floor / np.sum(shape**2))
    log = LogData(t=clean_log.t, theta=clean_log.theta,
                  wrench=clean_log.wrench + scale * shape * data.fs, temp_c=clean_log.temp_c)
    verdict = diagnose(log, baseline, seed=0)
    if named:
        assert verdict["present"] == ["stiffness_mismatch"]
        assert verdict["below_noise"] == []
    else:
        assert verdict["present"] == [] and verdict["ladder"] == []
        faint = {f["name"]: f for f in verdict["below_noise"]}
        assert faint["stiffness_mismatch"]["share_of_noise_floor"] < verdicts.NOISE_SHARE


def _leftover(shapes, structured, cart, separable):
    rows = [{"best": b, "structured": s} for b, s in zip(shapes, structured)]
    return {"joints": [j + 1 for j in range(3) if structured[j]], "per_joint": rows,
            "cartesian": {"share": cart, "separable_share": separable}}


def test_a_harness_leftover_is_pose_dependent_even_when_proximal_joints_look_like_rates():
    """A force on the plate, clamped off its centre: the proximal joints' leftover can look
    like a rate error of their own, but the gimbal's follows the plate's position."""
    from delta6.diagnosis.leftover import _verdict_shape
    odd, coupled = "odd polynomial", "coupled across joints"
    shapes = [odd, odd, odd, None, coupled, coupled]
    assert _verdict_shape(_leftover(shapes, [True] * 3 + [False, True, True], 0.95, 0.94)) \
        == "pose-dependent in Cartesian space"
    # Coupling only in joints at the noise floor, or a force the joints' own angles explain
    # better than the plate's position: the joints' own shape.
    assert _verdict_shape(_leftover(shapes, [True] * 3 + [False] * 3, 0.95, 0.94)) == odd
    assert _verdict_shape(_leftover(shapes, [True] * 6, 0.08, 0.9)) == odd


def test_implausible_families_leave_one_at_a_time_the_furthest_out_first():
    """Geometry errors soaking up a harness push the spring rates out of bounds too; only
    the furthest out leaves, and the rest are judged again without it."""
    def check(*ratios):
        return {"plausible": max(ratios) <= 1.0,
                "checks": [{"quantity": "q", "largest": r, "limit": 1.0, "ratio": r}
                           for r in ratios]}
    checks = {"geometry_error": check(0.5, 2.4), "stiffness_mismatch": check(1.3),
              "encoder_offset": check(0.2)}
    assert verdicts.furthest_out_of_bounds(checks, ["stiffness_mismatch", "geometry_error"]) \
        == "geometry_error"


@given(arrays(float, (300, 6), elements=st.floats(-1, 1)),
       st.lists(arrays(np.float32, (300, 6), elements=st.floats(-1, 1, width=32)),
                min_size=1, max_size=4))
def test_the_ladder_one_axis_at_a_time_is_the_ladder_of_all_axes_at_once(y, preds):
    """The ladder settles each axis on its own column (long logs: one column's trials in
    memory, not six); every figure is the one the six axes at once give, to the bit."""
    weights, p99s, final, sses, refits = ladder.monotone(y, preds)
    before, before_p99 = np.zeros_like(y), ladder.baseline_p99(y)
    for pred, a_got, p99_got, sse_got, refit_got in zip(preds, weights, p99s, sses, refits):
        assert np.array_equal(refit_got, ladder.p99_of_difference(y, pred))
        step = np.subtract(pred, before, dtype=float)
        a, after, open_axes = np.zeros(6), before_p99.copy(), np.ones(6, dtype=bool)
        for alpha in ladder.ALPHAS[ladder.ALPHAS > 0]:
            trial = ladder.p99_of_difference(y, before + alpha * step)
            take = open_axes & (trial <= before_p99)
            a[take], after[take] = alpha, trial[take]
            open_axes &= ~take
        before[:, a > 0] += a[a > 0] * step[:, a > 0]
        assert np.array_equal(a_got, a) and np.array_equal(p99_got, after)
        assert sse_got == ladder.squared_error(y, before)
        before_p99 = after
    assert np.array_equal(final, before)
