"""The blind benchmark's scoring of the extended figures, on constructed verdicts."""
from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from delta6.evaluation.gap_benchmark import FALSE_NAME_SHARE, score_extended, weak_names


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
