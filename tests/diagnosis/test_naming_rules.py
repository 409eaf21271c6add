"""The naming rules beyond the selection: which families the verdict names, which stay in the
ladder unnamed (partial: a structured leftover they may be fragments of), and which group
members a group verdict names."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delta6 import twin
from delta6.diagnosis import run as run_module
from delta6.diagnosis import selection, verdicts
from delta6.diagnosis.data import GapData
from delta6.diagnosis.run import (
    MISSING_SHARE,
    NAME_SHARE,
    PARTIAL_SHARE,
    SMALL_SHARE,
    diagnose,
    first_explanation,
    minor_families,
    names_together,
    partial_families,
)
from delta6.diagnosis.terms import TERMS
from delta6.link.logfile import LogData
from delta6.twin.pushes import AxisPushes
from delta6.twin.streams import stream

from support.twinkit import lugre_friction_log, twin_log

TERM_BY_NAME = {t.name: t for t in TERMS}


def steps_of(shares: dict) -> list[dict]:
    return [{"added": n, "share_of_gap": s} for n, s in shares.items()]


def test_a_family_explaining_less_than_the_structured_leftover_is_a_fragment_of_it():
    shares = {"big": 0.60, "small": 0.04, "overlapping": 0.03}
    alone = {"big": 0.70, "small": 0.05, "overlapping": 0.20}
    steps = steps_of(shares)
    missing = 0.08                       # under MISSING_SHARE: the old clause does not fire
    assert missing < MISSING_SHARE
    found = partial_families(steps, shares, shares, alone, missing, spared=set())
    # "small" explains less than the leftover both in the model and alone; "overlapping"
    # carries little in the model but alone explains more than the leftover (its share is
    # taken by neighbours, not picked up from them); "big" carries a lot.
    assert found == [{"name": "small", "share_of_gap": 0.04, "fragment": True,
                      "leftover_share": missing}]
    # With a leftover smaller than what it carries, it is named.
    assert partial_families(steps, shares, shares, alone, 0.03, spared=set()) == []
    # A white leftover (missing 0) never strikes a name.
    assert partial_families(steps, shares, shares, alone, 0.0, spared=set()) == []
    # Spared families (a confirmed signature, the first explanation) stay named.
    assert partial_families(steps, shares, shares, alone, missing, spared={"small"}) == []
    # What it carries with the families it trades with counts (a refinement's partner).
    traded = {**shares, "small": 0.30}
    assert partial_families(steps, shares, traded, alone, missing, spared=set()) == []


def test_a_small_name_needs_to_stand_on_its_own():
    traded = {"big": 0.60, "compensator": 0.03, "absorbed": 0.03, "tiny": 0.01,
              "medium": 0.06}
    alone = {"big": 0.70, "compensator": 0.01, "absorbed": 0.20, "tiny": 0.30,
             "medium": -0.02}
    assert NAME_SHARE < 0.03 < SMALL_SHARE < 0.06
    found = minor_families(steps_of(traded), traded, alone, eligible=set(traded))
    # Under SMALL_SHARE both in the model and alone: not named. A family its neighbours
    # absorb in the model but that explains a lot alone keeps its name; so does one that
    # carries more than SMALL_SHARE in the model; under NAME_SHARE nothing saves a name.
    assert [m["name"] for m in found] == ["compensator", "tiny"]
    assert found[0]["share_alone"] == 0.01
    # Families not eligible (already partial) are left alone.
    assert minor_families(steps_of(traded), traded, alone, eligible={"big", "medium"}) == []


def test_a_confirmed_family_is_spared_the_trading_test_but_not_the_small_one():
    traded = {"big": 0.60, "traded_away": 0.01, "small": 0.02}
    alone = {"big": 0.70, "traded_away": 0.30, "small": 0.03}
    steps = steps_of(traded)
    # Unconfirmed, both go: one for trading, one for being small both ways.
    assert [m["name"] for m in minor_families(steps, traded, alone, set(traded))] == [
        "traded_away", "small"]
    # Its signature tells a family from its neighbours (a backlash whose dwell shows it
    # though friction and hysteresis take its share), but not that it matters: a play of a
    # few counts that removes under SMALL_SHARE both ways is still not named.
    found = minor_families(steps, traded, alone, set(traded),
                           confirmed={"traded_away", "small"})
    assert [(m["name"], m["confirmed"]) for m in found] == [("small", True)]


def test_a_sizeable_structured_leftover_still_strikes_every_small_family():
    shares = {"big": 0.60, "small": 0.04, "overlapping": 0.03}
    alone = {"big": 0.70, "small": 0.05, "overlapping": 0.20}
    found = partial_families(steps_of(shares), shares, shares, alone, MISSING_SHARE,
                             spared=set())
    assert [p["name"] for p in found] == ["small", "overlapping"]
    assert not any(p["fragment"] for p in found)


def test_the_first_explanation_is_spared_when_it_removes_a_large_share_alone():
    base = np.ones(60)
    steps = steps_of({"a": 0.2, "b": 0.1})
    strong = {"a": np.full(60, 1.0 - PARTIAL_SHARE - 0.05), "b": np.full(60, 0.9)}
    weak = {"a": np.full(60, 1.0 - PARTIAL_SHARE + 0.05), "b": np.full(60, 0.9)}
    chosen = [s["added"] for s in steps]
    traded = {"a": 0.2, "b": 0.1}
    assert first_explanation(strong, base, ["a", "b"], chosen, traded) == {"a"}
    # Only forward selection's first pick: the later one, however large alone, may be
    # absorbing.
    assert first_explanation(strong, base, ["b", "a"], chosen, traded) == set()
    assert first_explanation(weak, base, ["a", "b"], chosen, traded) == set()
    assert first_explanation(strong, base, [], chosen, traded) == set()
    # The first pick the backward test took out spares no later family.
    assert first_explanation(strong, base, ["a", "b"], ["b"], traded) == set()


def test_a_first_explanation_the_later_families_took_over_is_not_spared():
    """Large alone, but carrying under SMALL_SHARE of the gap in the final model with the
    families it trades with: what it explained, the others now explain."""
    base = np.ones(60)
    strong = {"a": np.full(60, 1.0 - PARTIAL_SHARE - 0.05), "b": np.full(60, 0.9)}
    chosen = ["a", "b"]
    assert first_explanation(strong, base, chosen, chosen,
                             {"a": SMALL_SHARE * 0.8, "b": 0.1}) == set()
    assert first_explanation(strong, base, chosen, chosen,
                             {"a": SMALL_SHARE, "b": 0.1}) == {"a"}


def test_a_lone_small_name_is_not_rescued_by_the_every_name_rule():
    """The minor rule strikes every name: families struck only for trading are named after
    all when together they carry the naming share; a small name must carry the small-name
    share even together."""
    traded_only = [{"name": "a", "share_with_traded": 0.01, "share_alone": 0.2}]
    small = [{"name": "a", "share_with_traded": 0.03, "share_alone": 0.02}]
    assert names_together(traded_only, NAME_SHARE)
    assert not names_together(traded_only, 0.9 * NAME_SHARE)
    assert not names_together(small, 0.03)
    assert names_together(small, SMALL_SHARE)


def test_a_latency_under_one_axis_pushes_is_named_alone_and_leaves_nothing_structured(
        baseline):
    """A first-order latency under one-axis pushes: the family (a delay's expansion) follows
    it whole on a continuous path; nothing else is named and the leftover is white. (When the
    pushes' path jumped at the axes' boundaries, the jumps left the latency's misfit
    structured and friction's speed terms took part of its share.)"""
    seed = 3622
    effect = twin.make_effect("sensor_latency", seed=seed, formulation="first_order",
                              magnitude=0.76)
    path = AxisPushes(baseline, 300.0, stream(seed, "pushes"))
    r = twin.simulate(baseline, [effect], duration_s=300.0, rate_hz=50.0, seed=seed,
                      record_temp=True, path=path)
    verdict = diagnose(LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c),
                       baseline, seed=0)
    assert verdict["present"] == ["sensor_latency"]
    assert [s["added"] for s in verdict["ladder"]] == ["sensor_latency"]
    assert not verdict["unexplained"]["verdict"]["structured"]


def test_an_absorber_of_an_unknown_effect_that_explains_less_than_the_leftover_is_not_named(
        baseline):
    """A harness the vocabulary lacks (its family and the two other newest withheld): an
    encoder offset picks up a few per cent of it, less, alone and in the model, than the
    final model leaves structured, while the leftover is under the partial rule's sizeable
    share: it stays in the ladder as a fragment of the leftover, not named."""
    effect = twin.make_effect("harness", seed=61, magnitude=0.8)
    r = twin.simulate(baseline, [effect], duration_s=240.0, rate_hz=50.0, seed=61,
                      record_temp=True)
    log = LogData(t=r.t, theta=r.theta, wrench=r.wrench, temp_c=r.temp_c)
    withheld = {"harness", "nonlinear_spring", "encoder_periodic_error"}
    verdict = diagnose(log, baseline, seed=0,
                       terms=[t for t in TERMS if t.name not in withheld])
    fragments = {p["name"]: p for p in verdict["partial"]}
    assert "encoder_offset" in fragments and fragments["encoder_offset"]["fragment"]
    assert "encoder_offset" not in verdict["present"]
    assert "encoder_offset" in [s["added"] for s in verdict["ladder"]]
    alone = {c["name"]: c["score"] for c in verdict["candidates"]}
    own = {s["added"]: s["share_of_gap"] for s in verdict["ladder"]}
    left = verdict["unexplained"]["share_of_squared_error"]
    missing = fragments["encoder_offset"]["leftover_share"]
    assert max(alone["encoder_offset"], own["encoder_offset"]) < missing < MISSING_SHARE
    assert missing <= left
    assert verdict["unexplained"]["verdict"]["structured"]


@pytest.fixture(scope="module")
def hysteresis_problem(baseline):
    r = twin.simulate(baseline, [twin.make_effect("spring_hysteresis", seed=44, magnitude=0.9)],
                      duration_s=120, seed=44)
    data = GapData.from_log(LogData(t=r.t, theta=r.theta, wrench=r.wrench), baseline)
    terms = [TERM_BY_NAME["spring_hysteresis"], TERM_BY_NAME["joint_friction"]]
    return selection.build_problem(data, terms)


def test_a_group_verdict_names_no_member_lost_in_the_noise(hysteresis_problem):
    problem = hysteresis_problem
    info = {"forward": ["spring_hysteresis", "joint_friction"], "dropped": ["joint_friction"],
            "base": selection.heldout_block_sse(problem, [])}
    assert len(verdicts.groups(problem, ["spring_hysteresis"], info)) == 1
    # Friction removes nothing beyond the noise next to the hysteresis: the log shows
    # nothing of it the hysteresis does not explain, and the ladder does not model it.
    assert verdicts.groups(problem, ["spring_hysteresis"], info,
                           faint={"joint_friction"}) == []


def test_the_tied_fit_is_the_fit_of_the_stiffening_in_its_physical_form(baseline):
    """heldout_block_sse_tied works on Gram summaries; it must equal building the columns of a
    stiffening spring with the nominal rate at rest (|u| and u^2 times the nominal torque,
    nothing taken out) and fitting them in place of both families."""
    from dataclasses import replace

    from delta6.diagnosis.terms import NONLINEAR_REF_RAD, NONLINEAR_STRAIGHT_PART, _torque_columns
    log = twin_log(baseline, [twin.make_effect("nonlinear_spring", seed=5,
                                                      formulation="progressive")], 5)
    data = GapData.from_log(log, baseline)

    def physical(d):
        u = d.theta / NONLINEAR_REF_RAD
        tau = d.params.k * d.theta
        return _torque_columns(d, np.stack([tau * np.abs(u), tau * u**2], axis=-1))

    spring = TERM_BY_NAME["nonlinear_spring"]
    raw = replace(spring, name="physical", build=physical, refines=None, straight_part=None)
    names = ["encoder_offset", "stiffness_mismatch", "nonlinear_spring"]
    problem = selection.build_problem(data, [TERM_BY_NAME[n] for n in names] + [raw])
    tied = selection.heldout_block_sse_tied(problem, names, "nonlinear_spring",
                                            "stiffness_mismatch", NONLINEAR_STRAIGHT_PART)
    explicit = selection.heldout_block_sse(problem, ["encoder_offset", "physical"])
    np.testing.assert_allclose(tied, explicit, rtol=1e-6, atol=1e-12)
    # And it is a different model from both families free (the rate error is tied).
    free = selection.heldout_block_sse(problem, names)
    assert not np.allclose(tied, free, rtol=1e-6)


def test_a_stiffening_spring_alone_names_no_rate_error_and_a_real_one_is_kept(baseline):
    """A cubic stiffening spring (nominal rate at rest) leaves its straight-line part to the
    spring-rate family: without the rule both were named. With a rate error of its own
    beside the spring, both are named."""
    spring = twin.make_effect("nonlinear_spring", seed=7, formulation="cubic", magnitude=0.8)
    verdict = diagnose(twin_log(baseline, [spring], 7), baseline, seed=0)
    assert verdict["present"] == ["nonlinear_spring"]
    assert [s["name"] for s in verdict["straight_part"]] == ["stiffness_mismatch"]
    assert verdict["straight_part"][0]["share_of_noise_floor"] < verdicts.NOISE_SHARE
    # Unnamed, not dropped: the ladder keeps the straight part (the correction works).
    assert "stiffness_mismatch" in [s["added"] for s in verdict["ladder"]]
    assert all(s["named"] == (s["added"] in verdict["present"]) for s in verdict["ladder"])
    rate = twin.make_effect("stiffness_mismatch", seed=8, magnitude=0.5)
    both = diagnose(twin_log(baseline, [spring, rate], 7), baseline, seed=0)
    assert set(both["present"]) == {"nonlinear_spring", "stiffness_mismatch"}
    assert both["straight_part"] == []


def _encoder_coefficients(curve) -> np.ndarray:
    """The encoder family's coefficients (six joints alike) that fit an angle error curve
    over the joint range."""
    from delta6.diagnosis.terms import ENCODER_HARMONICS, NONLINEAR_REF_RAD
    q = np.linspace(-NONLINEAR_REF_RAD, NONLINEAR_REF_RAD, 201)
    basis = np.stack([f for h in ENCODER_HARMONICS
                      for f in (np.sin(h * q), np.cos(h * q) - 1.0)], axis=1)
    one = np.linalg.lstsq(basis, curve(q), rcond=None)[0]
    return np.tile(one, 6)


def _bend(coef) -> float:
    checks = TERM_BY_NAME["encoder_periodic_error"].plausibility(coef)
    return {c["quantity"]: c for c in checks}["angle_error_beyond_line_rad"]


@settings(max_examples=60, deadline=None)
@given(amplitude=st.floats(0.0, 0.017), phases=st.lists(st.floats(0.0, 6.3), min_size=4,
                                                         max_size=4))
def test_a_magnets_periodic_error_never_bends_beyond_the_encoder_limit(amplitude, phases):
    """Any magnet error up to a degree in its first harmonic, falling as 1/h, with any
    phases: within the encoder family's bend limit, so a real encoder error stays plausible."""
    def curve(q):
        return sum(amplitude / h * (np.sin(h * q + p) - np.sin(p))
                   for h, p in zip((1, 2, 3, 4), phases))
    bend = _bend(_encoder_coefficients(curve))
    assert bend["largest"] <= bend["limit"]


def test_a_stiffening_springs_curve_is_no_encoder_error():
    """The angle-equivalent curve of a stiffening spring of 8 % at the reference deflection
    (the torque k q s (q / q_ref)^2 divided by the rate k) bends beyond the limit: fitted by
    the encoder family, it is implausible, and the family leaves it to nonlinear_spring."""
    from delta6.diagnosis.terms import NONLINEAR_REF_RAD
    bend = _bend(_encoder_coefficients(lambda q: 0.08 * q * (q / NONLINEAR_REF_RAD) ** 2))
    assert bend["largest"] > bend["limit"]


def test_a_small_member_beside_a_larger_one_is_named_in_the_group(hysteresis_problem):
    """Friction named beside hysteresis with under 5 % of the gap of its own: the two trade,
    and the verdict says "and/or" with the hysteresis named alone; both stay in the ladder."""
    problem = hysteresis_problem
    chosen = ["spring_hysteresis", "joint_friction"]
    present, groups = verdicts.fold_small_members(
        problem, chosen, chosen, {"spring_hysteresis": 0.6, "joint_friction": 0.01}, [],
        SMALL_SHARE)
    assert present == ["spring_hysteresis"]
    (g,) = groups
    assert g["members"] == chosen and g["named_alone"] == ["spring_hysteresis"]
    assert g["folded"] == ["joint_friction"]
    base = selection.heldout_block_sse(problem, []).sum()
    together = (base - selection.heldout_block_sse(problem, chosen).sum()) / base
    assert g["share_of_gap"] == pytest.approx(together)
    assert "spring_hysteresis and/or joint_friction" in g["text"]
    # A member with a share of its own keeps its name; a lone member is never folded.
    assert verdicts.fold_small_members(problem, chosen, chosen,
                                       {"spring_hysteresis": 0.6, "joint_friction": 0.08}, [],
                                       SMALL_SHARE) == (chosen, [])
    assert verdicts.fold_small_members(problem, ["joint_friction"], chosen,
                                       {"joint_friction": 0.01}, [], SMALL_SHARE) \
        == (["joint_friction"], [])
    # A member its own signature confirms keeps its name (backlash's dwell).
    assert verdicts.fold_small_members(
        problem, chosen, chosen, {"spring_hysteresis": 0.6, "joint_friction": 0.01}, [],
        SMALL_SHARE, spared={"joint_friction"}) == (chosen, [])
    # An existing verdict for the group takes the folded member in (one verdict per group).
    earlier = {"group": g["group"], "members": ["spring_hysteresis", "backlash"],
               "named_alone": ["spring_hysteresis"], "share_of_gap": 0.5, "text": "x"}
    _, merged = verdicts.fold_small_members(
        problem, chosen, chosen, {"spring_hysteresis": 0.6, "joint_friction": 0.01}, [earlier],
        SMALL_SHARE)
    assert len(merged) == 1
    assert merged[0]["members"] == ["spring_hysteresis", "backlash", "joint_friction"]


def test_a_lugre_friction_names_the_hysteresis_it_trades_with_only_in_the_group(baseline):
    """A LuGre friction alone (its bristles give a small hysteresis-like loop): the hysteresis
    family takes 2.4 % of the gap of its own beside the friction's 17 %. Before the rule both
    were named; now the friction is, and the hysteresis only in the group's "and/or"."""
    verdict = diagnose(lugre_friction_log(baseline), baseline, seed=0)
    assert verdict["present"] == ["joint_friction"]
    (group,) = verdict["groups"]
    assert group["folded"] == ["spring_hysteresis"]
    assert group["named_alone"] == ["joint_friction"]
    assert set(group["members"]) == {"joint_friction", "spring_hysteresis"}
    # No name both present and folded; the ladder's flag is "in present"; the ladder keeps it.
    assert not set(verdict["present"]) & set(group["folded"])
    assert {s["added"]: s["named"] for s in verdict["ladder"]} == {
        "joint_friction": True, "spring_hysteresis": False}


def test_a_spring_and_an_encoder_error_form_a_group_apart_from_the_direction_dependent_one():
    """Both show as a joint torque error smooth in the joint's own angle: one group label
    (what the group rules key on), not the direction-dependent one; the rate error they
    refine or mimic is in no group."""
    spring, encoder = TERM_BY_NAME["nonlinear_spring"], TERM_BY_NAME["encoder_periodic_error"]
    assert spring.group is not None and spring.group == encoder.group
    assert spring.group != TERM_BY_NAME["joint_friction"].group
    assert TERM_BY_NAME["stiffness_mismatch"].group is None


def test_the_smooth_group_folds_an_encoder_error_beside_a_spring(baseline):
    """Folding works for the second group as for the first (the shares are given; the log
    gives the group's share), and the partial and minor rules weigh the two together."""
    spring = twin.make_effect("nonlinear_spring", seed=7, formulation="cubic", magnitude=0.8)
    data = GapData.from_log(twin_log(baseline, [spring], 7), baseline)
    names = ["nonlinear_spring", "encoder_periodic_error"]
    problem = selection.build_problem(data, [TERM_BY_NAME[n] for n in names])
    present, groups = verdicts.fold_small_members(
        problem, names, names, {"nonlinear_spring": 0.5, "encoder_periodic_error": 0.01}, [],
        SMALL_SHARE)
    assert present == ["nonlinear_spring"]
    assert groups[0]["group"] == TERM_BY_NAME["nonlinear_spring"].group
    assert groups[0]["folded"] == ["encoder_periodic_error"]
    assert groups[0]["named_alone"] == ["nonlinear_spring"]
    assert groups[0]["share_of_gap"] > 0.5
    # Group shares: each member carries what taking both out costs, more than its own
    # share (each stands in for part of the other).
    base = selection.heldout_block_sse(problem, []).sum()
    full = selection.heldout_block_sse(problem, names).sum()
    together = run_module.group_shares(problem, names, base)
    both = (base - full) / base
    for n in names:
        own = (selection.heldout_block_sse(problem, [m for m in names if m != n]).sum()
               - full) / base
        assert together[n] == pytest.approx(both)
        assert both > own


def test_a_family_must_remove_one_axis_worth_of_the_white_noise_to_be_named():
    """The naming criterion: the held-out squared error a family removes against the noise
    floor over the six axes; one axis's worth (a sixth of the floor) names it, less does not,
    and with no noise estimate every gain counts."""
    floor = 6.0 * 1000 * 0.01         # six axes x 1000 samples x noise variance 0.01
    assert verdicts.above_noise(floor / 6, floor)
    assert not verdicts.above_noise(floor / 6 * 0.999, floor)
    assert not verdicts.above_noise(floor / 12, floor)
    assert verdicts.above_noise(1e-12, 0.0)
