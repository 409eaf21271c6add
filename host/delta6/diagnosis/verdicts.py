"""Verdicts beyond "present": effects the log cannot tell apart (group verdicts) and fits that
are not physically believable (plausibility).

Group verdicts. Some families describe physically different causes with nearly the same
signature on a given log: friction, hysteresis and backlash are all direction-dependent joint
torques. When forward selection found two members of a group significant one after the other
(the later one removing at least ``GROUP_MIN_GAIN`` of what was left) and the backward test
then dropped one of them (its share was absorbed by the other), the honest answer names the
group, "direction-dependent joint torque: backlash and/or spring_hysteresis, together N % of
the gap", rather than silently keeping one. A stiffening spring and an encoder's periodic
error are the other group: both are a joint torque error smooth in the joint's own angle.
(The pose-dependent families, offsets, rates, geometry, are nested enough that the backward
test's choice among them is the better answer; they form no group.)
"""
from __future__ import annotations

import numpy as np

from delta6.core.model import ENCODER_COUNT_RAD
from delta6.diagnosis import selection

#: A member the backward test dropped joins a group verdict only if, when forward selection
#: added it, it removed at least this share of the held-out error left (a passenger that picks
#: up a few per cent of a neighbour's misfit is not a second explanation).
GROUP_MIN_GAIN = 0.10


def groups(problem: selection.Problem, kept: list[str], info: dict,
           faint=frozenset()) -> list[dict]:
    """Group verdicts: per group with a member dropped by the backward test after forward
    selection found it significant, the members (kept and dropped) and their joint share of
    the analytical model's held-out squared error. A dropped member in ``faint`` (one that
    removes less than the noise criterion in the final model, :func:`drop_faint`) is no
    member: the log shows nothing of it beyond what its neighbours explain, and the ladder
    does not model it."""
    gains = info.get("forward_gain", {})
    dropped = [n for n in info.get("dropped", []) if gains.get(n, 1.0) >= GROUP_MIN_GAIN
               and n not in faint]
    by_group: dict[str, list[str]] = {}
    for name in info.get("forward", []):
        group = problem.terms[name].group
        if group is not None and (name in kept or name in dropped):
            by_group.setdefault(group, []).append(name)
    out = []
    base = info["base"].sum()
    for label, members in by_group.items():
        if len(members) < 2 or not any(m in dropped for m in members):
            continue
        share = selection.removal_share(
            problem, kept + [m for m in members if m not in kept], members, base)
        out.append({"group": label, "members": members,
                    "named_alone": [m for m in members if m in kept],
                    "share_of_gap": share, "text": group_text(label, members, share)})
    return out


def group_text(label: str, members: list[str], share: float) -> str:
    return f"{label}: {' and/or '.join(members)}, together {100 * share:.0f} % of the gap"


def fold_small_members(problem: selection.Problem, present: list[str], chosen: list[str],
                       own: dict, groups_found: list[dict], below: float, spared=frozenset()
                       ) -> tuple[list[str], list[dict]]:
    """Named members of a group that carry under ``below`` of the gap of their own (``own``:
    what taking each out of the final model ``chosen`` costs) beside a named member of the
    same group that carries more: their share is what the group's members trade, and the
    log tells the effect apart from its neighbours no better than for a member the backward
    test dropped. They leave ``present`` for the group verdict (one is made, or the group's
    verdict takes them), which keeps them in the ladder and says "and/or"; the member that
    carries most stays named alone, and so does one its own signature confirms (``spared``:
    backlash's dwell, which its neighbours do not show). Returns the new ``present`` and
    group verdicts."""
    present = list(present)
    out = [dict(g) for g in groups_found]
    by_label: dict[str, list[str]] = {}
    for name in present:
        label = problem.terms[name].group
        if label is not None:
            by_label.setdefault(label, []).append(name)
    base = selection.heldout_block_sse(problem, []).sum()
    full = selection.heldout_block_sse(problem, chosen).sum()
    for label, named in by_label.items():
        if len(named) < 2:
            continue
        lead = max(named, key=lambda n: own.get(n, 0.0))
        small = [n for n in named if n != lead and n not in spared
                 and own.get(n, 0.0) < below]
        if not small:
            continue
        for n in small:
            present.remove(n)
        verdict = next((g for g in out if g["group"] == label), None)
        members = list(dict.fromkeys((verdict["members"] if verdict else []) + named))
        share = selection.removal_share(problem, chosen, members, base, full) \
            if base > 0 else 0.0
        folded = {"group": label, "members": members,
                  "named_alone": [n for n in members if n in present],
                  "share_of_gap": share, "text": group_text(label, members, share),
                  "folded": small}
        out = [g for g in out if g["group"] != label] + [folded]
    return present, out


#: A play fitted beside a named hysteresis counts on a joint from this size (a few encoder
#: counts: beside a loop alone, development runs left less on all joints but one) ...
PLAY_BESIDE_RAD = 5 * ENCODER_COUNT_RAD
#: ... beyond three standard errors, and on at least this many joints (one or two joints'
#: play is as likely the loop's misfit there).
PLAY_BESIDE_JOINTS = 3


def play_beside(problem: selection.Problem, chosen: list[str], named,
                plausible_now: dict) -> dict | None:
    """A backlash the final model ``chosen`` leaves out beside a named hysteresis (in
    ``named``): fitted with the model on the whole log, a play of several counts on several
    joints. A hysteresis loop takes up most of a play's switch (it is a direction-dependent
    torque too), so the held-out error gains little from the play and the selection leaves
    it out; but the loop alone does not need one. The play must be plausible and leave every
    family that was plausible in the model (``plausible_now``: :func:`plausibility` of its
    fit) so. Returns the play per joint (rad) and the joints that show it, or None."""
    term = problem.terms.get("backlash")
    if term is None or "backlash" in chosen or "spring_hysteresis" not in named:
        return None
    names = list(chosen) + ["backlash"]
    coef = selection.fit(problem, names)
    width = len(term.param_names)
    cov = covariance(problem, names, coef)[-width:, -width:]
    per_joint = np.kron(np.eye(6), np.ones((1, width // 6)))     # the play: a joint's sum
    play = per_joint @ coef[-width:]
    se = np.sqrt(np.maximum(np.diag(per_joint @ cov @ per_joint.T), 0.0))
    joints = [j + 1 for j in range(6) if play[j] >= PLAY_BESIDE_RAD and play[j] > 3 * se[j]]
    if len(joints) < PLAY_BESIDE_JOINTS:
        return None
    # The play must be believable, and must not push a neighbour out of bounds.
    after = plausibility(problem, names, coef)
    if not after["backlash"]["plausible"] or any(
            plausible_now[n]["plausible"] and not after[n]["plausible"] for n in chosen):
        return None
    return {"play_rad": play.tolist(), "joints": joints}


def join_play(problem: selection.Problem, chosen: list[str], present: list[str],
              groups_found: list[dict], beside: dict) -> list[dict]:
    """The group verdicts with backlash in the direction-dependent one (made of the hysteresis
    and the play when there is none): the log cannot tell the play from the loop."""
    label = problem.terms["backlash"].group
    base = selection.heldout_block_sse(problem, []).sum()
    verdict = next((g for g in groups_found if g["group"] == label), None)
    # Without a verdict, the loop and the play: a friction named alone beside them was told
    # apart from the loop by the selection.
    members = list(verdict["members"]) if verdict else ["spring_hysteresis"]
    members.append("backlash")
    share = selection.removal_share(problem, list(chosen) + ["backlash"], members, base) \
        if base > 0 else 0.0
    joined = {**(verdict or {"group": label}), "members": members,
              "named_alone": [m for m in members if m in present], "share_of_gap": share,
              "text": group_text(label, members, share), "play_beside": beside}
    return [g for g in groups_found if g["group"] != label] + [joined]


def covariance(problem: selection.Problem, names, coef: np.ndarray) -> np.ndarray:
    """Covariance of a fit's coefficients on all blocks: the residual variance of the fit
    (not just the noise: a family that misfits is less certain) times the regularised
    inverse Gram matrix."""
    cols = problem.cols(names)
    gram = problem.gram[:, cols][:, :, cols].sum(axis=0)
    xty = problem.xty[:, cols].sum(axis=0)
    rows = 6.0 * problem.bounds[-1]
    sse = problem.yty.sum() - 2 * coef @ xty + coef @ gram @ coef
    var = max(sse, 0.0) / max(rows - len(cols), 1.0)
    reg = gram + np.diag(problem.penalty[cols]) if problem.penalty is not None else gram
    scale = np.sqrt(np.maximum(np.diag(reg), 1e-300))
    inv = np.linalg.pinv(reg / np.outer(scale, scale)) / np.outer(scale, scale)
    return inv * var


def standard_errors(problem: selection.Problem, names, coef: np.ndarray) -> np.ndarray:
    """Standard errors of a fit's coefficients (:func:`covariance`)."""
    return np.sqrt(np.maximum(np.diag(covariance(problem, names, coef)), 0.0))


def plausibility(problem: selection.Problem, names, coef: np.ndarray) -> dict:
    """Per family in ``names`` (coefficients ``coef`` in their column order): every physical
    quantity against its limit, and whether the fit stays within all of them."""
    out = {}
    at = 0
    cov = covariance(problem, names, coef)
    for name in names:
        term = problem.terms[name]
        width = len(term.param_names)
        block = slice(at, at + width)
        checks = (term.plausibility(coef[block], cov[block, block])
                  + term.sign_checks(coef[block], cov[block, block]))
        at += width
        out[name] = {"plausible": all(c["ratio"] <= 1.0 for c in checks), "checks": checks}
    return out


def furthest_out_of_bounds(checks: dict, bad: list[str]) -> str:
    """The family of ``bad`` whose worst quantity is furthest beyond its limit (``checks``
    from :func:`plausibility`)."""
    return max(bad, key=lambda n: max(c["ratio"] for c in checks[n]["checks"]))


def rescue(problem: selection.Problem, kept: list[str], bad: list[str],
           others: list[str]) -> str | None:
    """The candidate among ``others`` with which every family of ``bad`` fits plausibly and the
    held-out error of ``kept`` drops the most (None: no such candidate)."""
    before = selection.heldout_block_sse(problem, kept).sum()
    best, best_sse = None, before
    for name in others:
        trial = kept + [name]
        checks = plausibility(problem, trial, selection.fit(problem, trial))
        if not all(checks[b]["plausible"] for b in bad) or not checks[name]["plausible"]:
            continue
        sse = selection.heldout_block_sse(problem, trial).sum()
        if sse < best_sse:
            best, best_sse = name, sse
    return best


#: A family is named only when the held-out squared error it removes is at least this share
#: of the white noise's over the whole log (six axes): one axis's worth. Less would not make
#: the leftover of any axis structured by the leftover verdict's own test, so nothing could
#: tell the family's cause from the noise or from a neighbouring, unknown effect.
NOISE_SHARE = 1.0 / 6.0


def noise_floor_sse(problem: selection.Problem) -> float:
    """Squared error white noise alone leaves over the log (FS-normalised, six axes)."""
    return 6.0 * float(problem.bounds[-1]) * problem.noise_var


def above_noise(sse_removed: float, floor: float) -> bool:
    return floor <= 0 or sse_removed >= NOISE_SHARE * floor


def drop_faint(problem: selection.Problem, names: list[str]) -> tuple[list[str], list[dict]]:
    """Drop, weakest first, every family whose own share (what taking it out of the model
    costs) is below the noise criterion; returns the rest and the dropped ones with their
    share of the gap and of the noise floor at the time they were dropped."""
    names = list(names)
    floor = noise_floor_sse(problem)
    base = selection.heldout_block_sse(problem, []).sum()
    dropped = []
    while names:
        full = selection.heldout_block_sse(problem, names).sum()
        costs = {n: selection.heldout_block_sse(problem, [m for m in names if m != n]).sum()
                 - full for n in names}
        weakest = min(costs, key=costs.get)
        if above_noise(costs[weakest], floor):
            break
        names.remove(weakest)
        dropped.append({"name": weakest, "share_of_gap": float(costs[weakest] / base),
                        "share_of_noise_floor": float(costs[weakest] / floor)})
    return names, dropped


def significant_joints(problem: selection.Problem, names, coef: np.ndarray,
                       name: str) -> set:
    """Joints (1..6) on which a per-joint family's fitted coefficients stand out by more than
    three standard errors (all of them for a family that is not per joint)."""
    se = standard_errors(problem, names, coef)
    at = 0
    for n in names:
        width = len(problem.terms[n].param_names)
        if n == name:
            c, s = coef[at:at + width], se[at:at + width]
            if width % 6:
                return set(range(1, 7))
            big = (np.abs(c) > 3.0 * s).reshape(6, -1).any(axis=1)
            return {j + 1 for j in range(6) if big[j]}
        at += width
    return set()


def order_refinements(problem: selection.Problem, present: list[str], chosen: list[str],
                      coef: np.ndarray) -> list[str]:
    """A family that refines another (``Term.refines``: a stiffening spring's straight-line
    part is a spring-rate error) comes first when both are named on common joints: the
    refinement explains the shape, the other its straight part."""
    out = list(present)
    for name in present:
        base = problem.terms[name].refines
        if base is None or base not in out or out.index(base) > out.index(name):
            continue
        if significant_joints(problem, chosen, coef, name) \
                & significant_joints(problem, chosen, coef, base):
            out.remove(name)
            out.insert(out.index(base), name)
    return out


def stand_ins(problem: selection.Problem, chosen: list[str], named: list[str],
              others: list[str]) -> dict:
    """Per family of ``named``, the families of ``others`` (not in the final model
    ``chosen``) that could take its place: with one of them instead, the model fits
    plausibly (every family of it), leaves a held-out squared error within the noise
    criterion of the final model's (:func:`above_noise`), and the stand-in wins back at
    least half of what taking the named family out costs (near the noise floor a loose
    look-alike would pass the first test alone). Families of one declared group, or one
    refining the other, are left to the group verdicts and the refinement rules."""
    full = selection.heldout_block_sse(problem, chosen).sum()
    floor = noise_floor_sse(problem)
    out = {}
    for name in named:
        term = problem.terms[name]
        rest = [n for n in chosen if n != name]
        cost = selection.heldout_block_sse(problem, rest).sum() - full
        for other in others:
            o = problem.terms[other]
            if other in chosen or (term.group is not None and o.group == term.group) \
                    or o.refines == name or term.refines == other:
                continue
            trial = rest + [other]
            sse = selection.heldout_block_sse(problem, trial).sum()
            if above_noise(sse - full, floor) or full + cost - sse < STAND_IN_SHARE * cost:
                continue
            checks = plausibility(problem, trial, selection.fit(problem, trial))
            if all(c["plausible"] for c in checks.values()):
                out.setdefault(name, []).append(other)
    return out


#: A stand-in wins back at least this share of what taking the named family out costs.
STAND_IN_SHARE = 0.5


def straight_parts(problem: selection.Problem, chosen: list[str],
                   named: list[str]) -> list[dict]:
    """Refined families of ``named`` that are nothing but the straight-line part of a named
    refinement (``Term.straight_part``). A stiffening spring's columns leave their
    straight-line part to the spring-rate family, which then fits a rate error whether one is
    there or not. The test puts the refinement in its physical form (a stiffening spring
    with the nominal rate at rest: its columns plus that straight part) in place of both:
    if the final model ``chosen`` loses less than the noise criterion that way (as for a
    family below the noise, :func:`drop_faint`), the log shows no rate error of its own."""
    base = selection.heldout_block_sse(problem, []).sum()
    floor = noise_floor_sse(problem)
    full = selection.heldout_block_sse(problem, chosen).sum()
    out = []
    for name in named:
        term = problem.terms[name]
        if term.straight_part is None or term.refines not in named:
            continue
        tied = selection.heldout_block_sse_tied(problem, chosen, name, term.refines,
                                                term.straight_part).sum()
        if not above_noise(tied - full, floor):
            out.append({"name": term.refines, "straight_part_of": name,
                        "share_of_gap": float((tied - full) / base) if base > 0 else 0.0,
                        "share_of_noise_floor": float((tied - full) / floor)
                        if floor > 0 else 0.0})
    return out
