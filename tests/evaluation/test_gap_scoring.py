"""The blind benchmark's scoring of the extended figures, on constructed verdicts and short twin
runs."""
from __future__ import annotations

from dataclasses import asdict

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delta6.diagnosis.leftover import JOINT_SHARE
from delta6.evaluation.gap_benchmark import (
    FALSE_NAME_SHARE,
    UNKNOWN_EFFECTS,
    Case,
    add_bends,
    beyond_line,
    carried_sizes,
    joint_bends,
    leftover_joints,
    on_joint,
    score_extended,
    weak_names,
)


def verdict(present, shares, groups=()):
    return {"kind": "mix", "truth": [], "present": list(present), "shares": dict(shares),
            "groups": [{"members": list(g)} for g in groups], "true_shrink": 0.0,
            "predicted_shrink": 0.0, "ladder": [], "baseline_p99": [0.0] * 6}


def test_a_name_carrying_under_the_share_is_weak_and_an_absent_one_too():
    r = verdict(["a", "b", "c"], {"a": 0.5, "b": 0.04})
    assert weak_names(r) == 2             # b carries 4 %, c is absent


def test_a_group_verdict_is_one_name_carrying_its_members_share():
    # "backlash and/or friction": friction absent, backlash carrying 30 %: a true statement.
    r = verdict(["hysteresis"], {"hysteresis": 0.6, "backlash": 0.3},
                groups=[("backlash", "joint_friction")])
    assert weak_names(r) == 0
    assert weak_names(r, per_member=True) == 1
    # A group whose members together carry under the share is one weak name.
    r = verdict(["hysteresis"], {"hysteresis": 0.9, "backlash": 0.02},
                groups=[("backlash", "joint_friction")])
    assert weak_names(r) == 1
    assert weak_names(r, per_member=True) == 2


def test_a_negative_share_does_not_make_a_group_weak():
    """A member whose error cancels another's has a negative share: it takes nothing from
    the group's statement about the others."""
    r = verdict(["a"], {"a": -0.5, "b": 0.2}, groups=[("a", "b")])
    assert weak_names(r) == 1                      # a, named alone
    assert weak_names(r, per_member=True) == 1


def test_an_effect_cancelling_another_carries_its_own_error_in_the_second_count():
    # A stiffening spring against a soft rate error: removing it raises the gap (share
    # -0.1) though its own error is a quarter of it; an absent name stays weak either way.
    r = verdict(["rate", "spring", "ghost"], {"rate": 0.8, "spring": -0.1})
    r["own_shares"] = {"rate": 0.9, "spring": 0.25}
    assert carried_sizes(r) == {"rate": 0.9, "spring": 0.25}
    assert weak_names(r) == 2
    assert weak_names(r, shares=carried_sizes(r)) == 1
    del r["own_shares"]                           # older records: the removal share
    assert carried_sizes(r) == r["shares"]


def test_a_member_named_alone_is_not_counted_again_through_its_group():
    r = verdict(["backlash"], {"backlash": 0.01}, groups=[("backlash", "spring_hysteresis")])
    assert weak_names(r, per_member=True) == 2     # backlash alone, hysteresis via the group
    assert weak_names(r) == 2                      # backlash alone, the group carrying 1 %


@given(st.dictionaries(st.sampled_from("abcdef"), st.floats(-0.5, 1.0), max_size=6),
       st.lists(st.sampled_from("abcdefgh"), unique=True, max_size=6),
       st.lists(st.lists(st.sampled_from("abcdefgh"), min_size=2, max_size=3, unique=True),
                max_size=2))
def test_counting_each_member_is_never_kinder_than_counting_groups(shares, present, groups):
    r = verdict(present, shares, groups)
    alone = sum(1 for n in present if shares.get(n, 0.0) < FALSE_NAME_SHARE)
    assert alone <= weak_names(r) <= weak_names(r, per_member=True)


def test_the_mix_figures_use_both_counts():
    runs = [verdict(["a"], {"a": 0.5, "b": 0.2}, groups=[("b", "x")]),
            verdict(["a", "y", "z"], {"a": 0.9})]
    s = score_extended(runs)
    assert s["mix_recall"] == 1.0                       # a, a and b (in the group) named
    assert s["mix_runs_at_most_one_false"] == 0.5       # the second run names y and z
    assert s["mix_false_names_max"] == 2
    assert s["mix_runs_at_most_one_false_member"] == 0.5
    assert s["mix_false_members_max"] == 2


def test_one_axis_top1_is_also_given_on_effects_carrying_enough_as_on_random_runs():
    def axis_single(name, share, present):
        return {**verdict(present, {name: share}), "kind": "axis",
                "truth": [{"name": name}]}
    runs = [axis_single("backlash", 0.9, ["backlash"]),
            axis_single("link_compliance", 0.08, []),            # too small: named nothing
            axis_single("thermal_drift", 0.4, ["stiffness_mismatch"])]
    s = score_extended(runs)
    assert s["axis_singles"] == 3 and s["axis_top1"] == pytest.approx(1 / 3)
    assert s["axis_singles_detectable"] == 2 and s["axis_top1_detectable"] == 0.5


# -- unknown effects: which joints a per-joint effect leaves a leftover on --------------------

def unknown_run(acting, found, leftover=None, shape="even polynomial"):
    truth = {"name": "encoder_periodic_error", "joints": list(acting)}
    if leftover is not None:
        truth["leftover_joints"] = list(leftover)
    return {"kind": "unknown", "truth": [truth], "present": [], "ladder": [],
            "baseline_p99": [0.0] * 6, "true_shrink": 0.0, "predicted_shrink": 0.0,
            "shares": {"encoder_periodic_error": 0.5},
            "leftover": {"structured": True, "joints": list(found), "shape": shape}}


def test_the_leftover_joints_are_those_bending_like_the_largest():
    bend = np.array([0.08, 0.0, 0.15, 0.0, 0.41, 0.0]) * 1e-3
    assert leftover_joints([1, 5], bend) == [5]          # j1: 4 % of j5's variance
    assert leftover_joints([3, 5], bend) == [5]          # j3: 13 % of j5's variance
    assert leftover_joints([3, 5], bend * [1, 1, 2, 1, 1, 1]) == [3, 5]   # 54 %
    # At the verdict's own share, exactly: a quarter of the variance is half the rms.
    assert JOINT_SHARE == 0.25
    assert leftover_joints([3, 5], np.array([0, 0, 0.5, 0, 1.0, 0])) == [3, 5]
    assert leftover_joints([3, 5], np.array([0, 0, 0.499, 0, 1.0, 0])) == [5]
    assert leftover_joints([2], bend) == []               # no bend at all: nothing to find


@given(st.lists(st.integers(1, 6), min_size=1, max_size=6, unique=True),
       st.lists(st.floats(0.0, 1e-2), min_size=6, max_size=6))
def test_the_leftover_joints_are_acting_joints_led_by_the_largest_bend(acting, bend):
    bend = np.asarray(bend)
    chosen = leftover_joints(acting, bend)
    assert set(chosen) <= set(acting)
    top = max(bend[j - 1] for j in acting)
    if top > 0:
        assert max(acting, key=lambda j: bend[j - 1]) in chosen
    else:
        assert chosen == []


def test_an_unknown_run_is_scored_on_the_joints_the_effect_bends():
    ok = score_extended([unknown_run([1, 5], [5], leftover=[5])])
    assert ok["unknown_leftover_ok"] == 1.0
    assert ok["unknown_leftover_ok_every_joint"] == 0.0   # j1 is acted on, not found
    # Records from before the bend was measured: every joint the effect acts on.
    old = score_extended([unknown_run([1, 5], [5])])
    assert old["unknown_leftover_ok"] == old["unknown_leftover_ok_every_joint"] == 0.0
    # Naming a joint the effect leaves straight is wrong too.
    assert score_extended([unknown_run([1, 5], [1, 5], leftover=[5])])[
        "unknown_leftover_ok"] == 0.0


def test_what_bends_is_measured_on_the_joints_the_effect_acts_on(baseline):
    """On the twin: an encoder's periodic error on joints 2 and 4 bends each of them; a
    spring-rate error (a straight line in each joint's angle) bends nowhere."""
    from delta6 import twin

    def simulate(effects):
        return twin.simulate(baseline, effects, duration_s=40.0, rate_hz=50.0, seed=3)

    clean = simulate([])
    encoder = twin.make_effect("encoder_periodic_error", seed=5, joints=[2, 4],
                               formulation="harmonics", amplitude_rad=0.01)
    alone = on_joint(encoder, 4)
    assert alone.joints == (4,)
    assert np.array_equal(np.nonzero(alone.params["amplitude_rad"])[0], [3])
    assert np.array_equal(alone.params["mount_angle_rad"], encoder.params["mount_angle_rad"])
    bend = joint_bends(baseline, encoder, simulate, clean)
    assert np.all(bend[[1, 3]] > 1e-4)                     # a few tenths of a mN*m
    assert np.all(bend[[0, 2, 4, 5]] == 0.0)
    rate = beyond_line(baseline, simulate([twin.make_effect("stiffness_mismatch", seed=5,
                                                            magnitude=1.0)]), clean)
    assert np.all(rate < 5e-6)                             # rounding: under 1 % of that
    # An encoder offset turns the geometry too (a curve in the angle of joints 1-3), but the
    # vocabulary's offset family names it whole: on its joint it bends by nothing.
    for j in (1, 2, 5):
        offset = twin.make_effect("encoder_offset", seed=5, joints=[j], magnitude=1.0)
        assert beyond_line(baseline, simulate([offset]), clean, j)[j - 1] < 0.05 * bend[1]
    with pytest.raises(ValueError, match="not a smooth curve"):
        joint_bends(baseline, twin.make_effect("backlash", seed=5), simulate, clean)


def test_records_without_bends_get_them_measured_again(root):
    """An earlier run's records are re-scored from the case they keep: the same twin run."""
    case = Case("unknown", ["encoder_periodic_error"], 7, [0.9],
                withhold=list(UNKNOWN_EFFECTS), joints=[[3]])
    record = unknown_run([3], [3])
    record["case"] = asdict(case)
    other = unknown_run([3], [3])                     # a harness-like run: no joints recorded
    other["case"] = asdict(Case("unknown", ["harness"], 8, [0.9]))
    design = str(root / "designs" / "delta6.toml")
    assert add_bends([record, other], design, duration_s=40.0) == 1
    truth = record["truth"][0]
    assert truth["leftover_joints"] == [3]
    assert len(truth["beyond_line_nm"]) == 6 and truth["beyond_line_nm"][2] > 0.0
    assert "leftover_joints" not in other["truth"][0]
    first = list(truth["beyond_line_nm"])
    assert add_bends([record], design, duration_s=40.0) == 1     # the same run, measured again
    assert record["truth"][0]["beyond_line_nm"] == first
