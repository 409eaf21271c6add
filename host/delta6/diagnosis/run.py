"""The whole diagnosis of one log: where the gap lies, which effects cause it, how far it
shrinks, and what is left. Returns one JSON-ready dict (keys documented in
``docs/diagnosis.md``).

Memory stays bounded on long logs: the candidate terms' columns are built piece by piece
twice (``stream``), once for the per-block Gram summaries every decision is made from, once
for the held-out predictions of the chosen models; only per-sample arrays of six values are
kept whole.
"""
from __future__ import annotations

import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from delta6.core.design import Design
from delta6.core.model import AXES, Params
from delta6.diagnosis import blas, excitation, gap, leftover, onchip, physics, selection, stream, unseen, verdicts
from delta6.diagnosis import ladder as ladder_mod
from delta6.diagnosis import terms as terms_mod
from delta6.diagnosis.data import DiagnosisInputError, GapData
from delta6.diagnosis.terms import TERMS
from delta6.link.logfile import LogData

#: A structured leftover holding at least this share of the analytical model's held-out
#: squared error beyond the white noise means the vocabulary misses something sizeable;
#: families carrying less than ``PARTIAL_SHARE`` of the gap (alone, or with the other members
#: of their group: ``group_shares``) are then reported as partial, not named.
MISSING_SHARE = 0.25
PARTIAL_SHARE = 0.30
#: A family whose removal from the final model costs less than this share of the gap (with
#: the families it trades with: ``group_shares`` with ``refinements``) stays in the ladder
#: but is not named (``minor``): in a mix, neighbouring families trade that much among
#: themselves, so such a name says little about which effect is there.
NAME_SHARE = 0.015
#: A family carrying less than this share of the gap in the final model (with the families
#: it trades with) is named only when it removes at least as much on its own: a small name
#: needs more evidence than a large one. Under it both ways, a family explains too little,
#: by itself or beside its neighbours, to be told from their trading (an encoder offset
#: correcting the constant parts of its neighbours' fits removes nothing alone). It is the
#: share under which the blind benchmark calls a name weak.
SMALL_SHARE = 0.05
#: Logs up to this many samples keep their columns in memory (no second pass).
KEEP_COLUMNS_SAMPLES = 30_000


#: Scratch disk a long log's diagnosis needs beyond its first pass's columns: the harness's
#: second pass (27 of ~270 columns) and the ladder's predictions, with room to spare.
SCRATCH_MARGIN = 1.25


def check_scratch(directory, samples: int, width: int) -> None:
    """Refuse, in one line and before the hours of work, a log whose columns the scratch
    folder cannot hold (float32, six axes; ``stream.ColumnCache``)."""
    need = SCRATCH_MARGIN * samples * 6 * width * 4
    free = shutil.disk_usage(directory).free
    if free < need:
        raise DiagnosisInputError(
            f"a log of {samples} samples needs about {need / 1e9:.1f} GB of scratch disk for "
            f"its columns, but {Path(directory).parent} has {free / 1e9:.1f} GB free: set "
            "TMPDIR to a folder with more room")


def missing_share(problem: selection.Problem, left_sse: float, base_sse: float) -> float:
    """The share of the analytical model's held-out squared error that the final model leaves
    beyond the white noise: what the vocabulary misses."""
    if base_sse <= 0:
        return 0.0
    return max(left_sse - verdicts.noise_floor_sse(problem), 0.0) / base_sse


def group_shares(problem: selection.Problem, chosen: list[str], base_sse: float,
                 refinements: bool = False) -> dict:
    """Per family of the final model ``chosen``, the share of the gap it carries for the
    partial rule: its own share (what taking it out costs), or, for a member of a group of
    families that absorb each other (friction, hysteresis and backlash: direction-dependent
    joint torques; a stiffening spring and an encoder error: smooth in the joint's angle),
    what taking the group's members out together costs. Each member's own
    share is then small however large their joint one: every one of them stands in for the
    others' part. With ``refinements``, a family and the one it refines (a stiffening spring
    and a spring-rate error: the first's straight-line part is the second's) count as such
    a group too. The sets are not closed under both links: a stiffening spring trades with
    the encoder error and the rate error, the rate error with the spring only."""
    if base_sse <= 0:
        return {n: 0.0 for n in chosen}
    full = selection.heldout_block_sse(problem, chosen).sum()
    out = {}
    for name in chosen:
        label = problem.terms[name].group
        members = {name} if label is None else {n for n in chosen
                                                if problem.terms[n].group == label}
        if refinements:
            members |= {n for n in chosen if problem.terms[n].refines == name
                        or problem.terms[name].refines == n}
        out[name] = selection.removal_share(problem, chosen, members, base_sse, full)
    return out


def minor_families(steps: list[dict], traded: dict, alone: dict, eligible,
                   confirmed=frozenset()) -> list[dict]:
    """The ladder's families of ``eligible`` (named so far) that carry less than
    ``NAME_SHARE`` of the gap with the families they trade with (``traded``, from
    :func:`group_shares` with refinements), or less than ``SMALL_SHARE`` both so and on
    their own (``alone``: the share each removes alone), in ladder order. A family of
    ``confirmed`` (its own signature shows it) is told from its neighbours whatever they
    trade: only the second test applies to it, for it asks whether the effect matters."""
    def small(name):
        return max(traded[name], alone[name]) < SMALL_SHARE

    def trading(name):
        return name not in confirmed and traded[name] < NAME_SHARE

    return [{"name": s["added"], "share_of_gap": s["share_of_gap"],
             "share_with_traded": traded[s["added"]], "share_alone": alone[s["added"]],
             "confirmed": s["added"] in confirmed}
            for s in steps if s["added"] in eligible
            and (trading(s["added"]) or small(s["added"]))]


def names_together(minor: list[dict], together: float) -> bool:
    """When the minor rule would strike every name: whether the struck families, carrying
    ``together`` of the gap all at once (the final model against none), are named after
    all. By the share that struck them: a small name must stand on its own
    (``SMALL_SHARE``), and a set of small names together as much; families struck only for
    trading (under ``NAME_SHARE`` with their neighbours) by that share."""
    small = any(max(m["share_with_traded"], m["share_alone"]) < SMALL_SHARE for m in minor)
    return together >= (SMALL_SHARE if small else NAME_SHARE)


def partial_families(steps: list[dict], carried: dict, traded: dict, alone: dict,
                     missing: float, spared) -> list[dict]:
    """The partial rule: the ladder's families (but ``spared``) that carry less than
    ``PARTIAL_SHARE`` of the gap (``carried``: :func:`group_shares`) when the final model
    leaves ``missing`` of the analytical model's held-out squared error structured beyond
    the white noise, and that is sizeable (``MISSING_SHARE``: the vocabulary misses
    something); or, whatever its size, when the family explains less than it, both in the
    final model with the families it trades with (``traded``: with refinements) and on its
    own (``alone``: the share it removes alone): it could be a fragment of that leftover (a
    neighbour's misfit it picks up, or part of an effect the vocabulary lacks), and its name
    would say nothing the leftover verdict does not. ``missing`` is 0 for a white
    leftover; each entry gives it (``leftover_share``)."""
    out = []
    for s in steps:
        name = s["added"]
        if name in spared or carried[name] >= PARTIAL_SHARE:
            continue
        fragment = max(traded[name], alone[name]) < missing
        if missing >= MISSING_SHARE or fragment:
            out.append({"name": name, "share_of_gap": s["share_of_gap"],
                        "fragment": bool(fragment and missing < MISSING_SHARE),
                        "leftover_share": missing})
    return out


def first_explanation(alone: dict, base_sse: np.ndarray, forward: list[str],
                      chosen: list[str], traded: dict) -> set:
    """The family forward selection took first (``forward[0]``: the single best explanation
    of the gap), if the final model ``chosen`` still has it, when it removes at least
    ``PARTIAL_SHARE`` of the held-out error on its own: no absorber of an effect the
    vocabulary lacks, even with a structured leftover and a neighbour sharing its features
    taking part of its share in the final model (a latency's misfit beside friction's speed
    terms). But only
    while it still carries ``SMALL_SHARE`` of the gap in the final model with the families it
    trades with (``traded``: :func:`group_shares` with refinements): one whose explanation
    the later families took over whole (a geometry error taking a harness's pull on the plate
    until a rate error and an offset took it from there) is no longer the explanation.
    Empty when it removes less, or when the backward test or the noise rule took it out."""
    if not forward or forward[0] not in chosen:
        return set()
    name = forward[0]
    return {name} if (selection.gain(base_sse, alone[name]) >= PARTIAL_SHARE
                      and traded[name] >= SMALL_SHARE) else set()


def harness_clamp(problem: selection.Problem, *, seed: int, min_gain: float,
                  confidence: float, min_share: float, progress=None
                  ) -> tuple[np.ndarray | None, bool, "Selected | None"]:
    """Where a cable or harness is clamped on the plate (plate frame, mm), from the affine
    part of the harness family's fit alone (``terms.harness_clamp``; the one-sided terms left
    out, they would take part of the force's change with the centre's displacement but none of
    its change with the tilt; and alone, for the families kept with it may be absorbing part
    of the harness), and whether the first pass's selection (with the plausibility checks)
    kept the family. The clamp is estimated also when the family was not kept but removes a
    significant share of the held-out error alone (the forward test's rule): a cable clamped
    far off the centre stretches mostly with the tilt, so a hinge in the centre's displacement
    misses most of it and a neighbouring family can win the first pass. None: no such
    family, or the clamp at the centre or implausibly far. Also returns the first pass's
    selection (:func:`selected`), for the decision to reuse (None without a harness family)."""
    if "harness" not in problem.terms:
        return None, False, None
    first = selected(problem, list(problem.terms), seed, min_gain=min_gain,
                     confidence=confidence, min_share=min_share, progress=progress)
    was_kept = "harness" in first.kept
    if not was_kept:
        boot = selection.stratified_gain(first.info["base"], first.alone["harness"],
                                         first.rng())
        if not float(np.quantile(boot, 1 - confidence)) > min_gain:
            return None, False, first
    cols = problem.cols(["harness"])[:terms_mod.HARNESS_AFFINE]
    gram = problem.gram[:, cols][:, :, cols].sum(axis=0)
    clamp = terms_mod.harness_clamp(selection.solve(gram, problem.xty[:, cols].sum(axis=0),
                                                    problem.penalty[cols]))
    size = float(np.linalg.norm(clamp))
    if not terms_mod.HARNESS_CLAMP_MIN_MM <= size <= terms_mod.HARNESS_CLAMP_MAX_MM:
        return None, was_kept, first
    return clamp, was_kept, first


def harness_affine(problem: selection.Problem, first: "Selected") -> np.ndarray:
    """The harness family's affine coefficients (``terms.HARNESS_AFFINE``), its one-sided
    terms left out, fitted with the other families the first pass kept: alone, in a mix, its
    tilt terms take the gimbal joints' own errors (a spring rate's error there is a torque
    growing with the tilt, as a clamp off the centre gives), and the clamp follows them."""
    others = [n for n in first.kept if n != "harness"]
    cols = np.concatenate([problem.cols(others),
                           problem.cols(["harness"])[:terms_mod.HARNESS_AFFINE]])
    gram = problem.gram[:, cols][:, :, cols].sum(axis=0)
    coef = selection.solve(gram, problem.xty[:, cols].sum(axis=0), problem.penalty[cols])
    return coef[len(cols) - terms_mod.HARNESS_AFFINE:]


@dataclass(frozen=True)
class Selected:
    """A pass's selection (:func:`select_plausible`'s results) and the random generator's
    state after it: the decision goes on from there exactly as if it had selected itself
    (the selection is the diagnosis's costliest step; it is not run twice)."""
    steps: list
    info: dict
    kept: list
    implausible: dict
    alone: dict
    rng_state: dict

    def rng(self) -> np.random.Generator:
        rng = np.random.default_rng()
        rng.bit_generator.state = self.rng_state
        return rng


def selected(problem: selection.Problem, names: list[str], seed: int, *, min_gain: float,
             confidence: float, min_share: float, progress=None) -> Selected:
    """:func:`select_plausible` from a generator seeded with ``seed``, kept for reuse."""
    rng = np.random.default_rng(seed)
    steps, info, kept, implausible, alone = select_plausible(
        problem, list(names), rng, min_gain=min_gain, confidence=confidence,
        min_share=min_share, progress=progress)
    return Selected(steps, info, kept, implausible, alone, rng.bit_generator.state)


def follows_better(data: GapData, problem: selection.Problem, terms, clamp, *,
                   significant: bool = False, seed: int = 0, min_gain: float = 0.0,
                   confidence: float = selection.CONFIDENCE, cable=None) -> bool:
    """Whether the harness family with its displacement at the estimated clamp ``clamp``
    (None: the centre) and, with ``cable`` (``terms.cable_search``), its one-sided part that
    one cable's, removes more of the held-out error, alone, than the first pass's (a pass
    over the harness's columns only): a clamp near the centre, or one the affine fit
    estimated poorly, can follow the data worse than the plate centre's displacement does.
    With ``significant`` (a family the first pass did not keep), it must also pass the
    forward test on its own: remove more than ``min_gain`` of the analytical model's held-out
    error at the bootstrap's lower quantile (the first pass's family may have fitted worse
    than nothing: a log that pushes one axis at a time stretches a slack cable in a few
    pushes only, and a set of hinges along fixed directions extrapolates to the others)."""
    harness = next(t for t in terms if t.name == "harness")
    trial = selection.build_problem(
        data, [terms_mod.harness_with_clamp(harness, clamp, cable)], keep_columns=False)
    at_clamp = selection.heldout_block_sse(trial, ["harness"])
    at_centre = selection.heldout_block_sse(problem, ["harness"])
    if not at_clamp.sum() < at_centre.sum():
        return False
    if not significant:
        return True
    base = selection.heldout_block_sse(problem, [])
    boot = selection.stratified_gain(base, at_clamp, np.random.default_rng(seed))
    return bool(float(np.quantile(boot, 1 - confidence)) > min_gain)


def _rows(problem: selection.Problem, cache, rows: slice, n: int, cols: np.ndarray):
    """Columns ``cols`` of ``problem`` at the samples ``rows`` of a log of ``n``: from the
    columns kept in memory, or read row by row from the first pass's ``cache`` (a few thousand
    rows, not the log). None when neither holds them."""
    if problem.x is not None:
        return problem.x[rows][:, :, cols]
    if cache is None:
        return None
    return cache.rows(range(*rows.indices(n)))[:, :, cols].astype(float)


def others_at_search(data: GapData, problem: selection.Problem, first: "Selected", cache=None):
    """The columns of the families the first pass kept beside the harness at the cable
    search's samples (``terms.search_rows``), or None: no such family, or their columns
    not at hand."""
    others = [n for n in first.kept if n != "harness"]
    if not others:
        return None
    return _rows(problem, cache, terms_mod.search_rows(len(data)), len(data),
                 problem.cols(others))


def harness_target(data: GapData, problem: selection.Problem, first: "Selected", cache=None,
                   x=None):
    """What a harness's cable is to explain at the cable search's samples
    (``terms.search_rows``, FS-normalised): the residual less the other families the first
    pass kept, fitted jointly with the harness family (their fit alone would take part of
    the cable). In a mix the raw residual is mostly the other effects', and the cable that
    best follows it is not the harness's. None (the raw residual) when the first pass kept
    no other family, or their columns are not at hand. ``x``: those columns
    (:func:`others_at_search`) when already read."""
    others = [n for n in first.kept if n != "harness"]
    if x is None:
        x = others_at_search(data, problem, first, cache)
    if x is None:
        return None
    coef = selection.fit(problem, others + ["harness"])[:len(problem.cols(others))]
    rows = terms_mod.search_rows(len(data))
    view = data.residual[rows] / data.fs
    return view - x @ coef


def _with_others(data: GapData, others: np.ndarray, clamp, cable) -> float:
    """The share of the residual at the cable search's samples that the harness family with
    ``clamp`` and ``cable`` explains together with the other families' columns ``others``
    there (in-sample: the candidates compared have as many parameters)."""
    view = terms_mod._search_view(data)
    y = (view.residual / view.fs).reshape(-1)
    own = terms_mod._harness(view, clamp, cable) / view.fs[None, :, None]
    x = np.concatenate([others, own], axis=2).reshape(len(y), -1)
    gram = x.T @ x
    coef = selection.solve(gram, x.T @ y)
    left = y - x @ coef
    total = float(y @ y)
    return 1.0 - float(left @ left) / total if total > 0 else 0.0


def harness_second_pass(data: GapData, problem: selection.Problem, terms, *, seed: int,
                        min_gain: float, confidence: float, min_share: float, progress=None,
                        cache=None):
    """The harness family of the second pass, or None: the clamp's offset
    (:func:`harness_clamp`, None: the centre) and the slack cable that best explains the
    residual with its stretch there (``terms.cable_search``), when, alone, it follows the data
    better than the first pass's family (:func:`follows_better`; for a family the first pass
    did not keep, also by the forward test's rule). Returns the family, the clamp, the
    cable (direction, slack in mm) and the first pass's selection."""
    clamp, was_kept, first = harness_clamp(problem, seed=seed, min_gain=min_gain,
                                           confidence=confidence, min_share=min_share,
                                           progress=progress)
    if "harness" not in problem.terms:
        return None, None, None, first
    x = others_at_search(data, problem, first, cache)
    target = harness_target(data, problem, first, x=x)
    direction, slack, _ = terms_mod.cable_search(data, clamp)
    if target is not None:
        # In a mix the cable is also sought in what the other families leave, and the clamp
        # also read from the affine fit beside them (``harness_affine``). Either can go
        # wrong: a gimbal spring-rate family kept beside a lone cable takes the part of its
        # stretch that the tilt gives. The clamp and cable that, with the other families,
        # explain the most of the residual stand.
        candidates = [(clamp, (direction, slack))]
        candidates.append((clamp, terms_mod.cable_search(data, clamp, target=target)[:2]))
        beside = terms_mod.harness_clamp(harness_affine(problem, first))
        if terms_mod.HARNESS_CLAMP_MIN_MM <= float(np.linalg.norm(beside)) \
                <= terms_mod.HARNESS_CLAMP_MAX_MM:
            candidates.append((beside, terms_mod.cable_search(data, beside,
                                                              target=target)[:2]))
        shares = [_with_others(data, x, c, cable) for c, cable in candidates]
        clamp, (direction, slack) = candidates[int(np.argmax(shares))]
    if clamp is None:
        # No clamp from the first pass: sought with the cable (a clamp kept at the centre
        # when none explains more).
        clamp, direction, slack, _ = terms_mod.cable_clamp_search(data, direction,
                                                                  target=target)
        if not np.linalg.norm(clamp) > 0:
            clamp = None
    cable = (direction, slack)
    if not follows_better(data, problem, terms, clamp, significant=not was_kept, seed=seed,
                          min_gain=min_gain, confidence=confidence, cable=cable):
        return None, None, None, first
    harness = next(t for t in terms if t.name == "harness")
    return terms_mod.harness_with_clamp(harness, clamp, cable), clamp, cable, first


def diagnose(log: LogData, design: Design, **kwargs) -> dict:
    """Diagnose a log read with ``delta6.link.logfile.read_log`` (see :func:`diagnose_data`)."""
    return diagnose_data(GapData.from_log(log, design), **kwargs)


def diagnose_data(data: GapData, **kwargs) -> dict:
    """The diagnosis of prepared data (the caller may reuse ``data``, e.g. for the report);
    see :func:`_diagnose` for the keywords."""
    with blas.one_thread():
        return _diagnose(data, **kwargs)


def _diagnose(data: GapData, *, seed: int = 0, progress=None,
              min_gain: float = selection.MIN_GAIN, confidence: float = selection.CONFIDENCE,
              min_share: float = selection.MIN_SHARE, terms=None) -> dict:
    """``terms``: the candidate families (default: all of ``TERMS``)."""
    started = time.perf_counter()
    if progress:
        progress("model and breakdowns")
    where = gap.where(data)
    baseline_p99 = ladder_mod.baseline_p99(data.residual / data.fs).tolist()
    # Long logs: 50..100 MB each (gap.where drops the position and the speed it used). The
    # model's wrench too, now that the residual is made (the pieces compute their own; a
    # later caller gets it again on demand).
    for name in ("residual_pct", "model"):
        data.__dict__.pop(name, None)
    # The velocity's fit, chosen once on the whole log (its pieces keep it).
    if data.velocity_window is None:
        data.velocity_window = terms_mod.friction_velocity_window(data)
        data.__dict__.pop("smooth_velocity", None)

    # Sized for the design at hand (the shipped design's terms are returned as they are).
    vocabulary = terms_mod.for_design(TERMS if terms is None else tuple(terms), data.design)
    terms = [t for t in vocabulary if t.available(data)]
    skipped = [t.name for t in vocabulary if not t.available(data)]
    signatures = {t.name: t.signature for t in terms if t.signature is not None}
    keep = len(data) <= KEEP_COLUMNS_SAMPLES
    with tempfile.TemporaryDirectory(prefix="delta6-diagnose-") as scratch:
        width = sum(len(t.param_names) for t in terms)
        if not keep:
            check_scratch(scratch, len(data), width)
        cache = None if keep else stream.ColumnCache(scratch, width)
        problem = selection.build_problem(data, terms, progress=progress,
                                          signatures=signatures, keep_columns=keep,
                                          cache=cache)
        second_term, clamp, cable, first = harness_second_pass(
            data, problem, terms, seed=seed, min_gain=min_gain, confidence=confidence,
            min_share=min_share, progress=progress, cache=cache)
        if second_term is not None:
            # Second pass: the harness's displacement at the clamp, its one-sided part the
            # cable found. It stands only when its selection keeps the harness family, the
            # reason for it (a hinge in the wrong place can leave the family below the
            # forward test).
            if progress:
                progress("harness: a cable {:.0f} mm off the centre, slack {:g} mm: second "
                         "pass".format(0.0 if clamp is None else float(np.linalg.norm(clamp)),
                                       cable[1]))
            second_terms = [second_term if t.name == "harness" else t for t in terms]
            second_cache = None
            if cache is not None:
                Path(scratch, "second").mkdir()
                # Only the harness's columns are new: the others are read from the first
                # pass's cache (a long log's is gigabytes of disk).
                second_cache = stream.ColumnCache(
                    Path(scratch, "second"), sum(len(t.param_names) for t in second_terms),
                    reuse=(cache, stream.reused_columns(terms, second_terms)))
            second = selection.build_problem(data, second_terms, progress=progress,
                                             signatures=signatures, keep_columns=keep,
                                             cache=second_cache)
            second_selected = selected(second, [t.name for t in second_terms], seed,
                                       min_gain=min_gain, confidence=confidence,
                                       min_share=min_share)
            if "harness" in second_selected.kept:
                problem, terms, cache, first = second, second_terms, second_cache, \
                    second_selected
            else:
                clamp, cable = None, None
                _drop(second_cache)
                if progress:
                    progress("second pass dropped: the harness is not kept with it")
            del second
        result = _decide(data, problem, terms, skipped, where, baseline_p99, cache, started,
                         seed=seed, progress=progress, min_gain=min_gain,
                         confidence=confidence, min_share=min_share, first=first,
                         scratch=None if keep else scratch)
        result["harness_clamp_mm"] = None if clamp is None else [float(v) for v in clamp]
        result["harness_cable"] = None if cable is None else {
            "direction": [float(v) for v in cable[0]], "slack_mm": float(cable[1])}
        return result


def beyond_encoders(data: GapData, final_pct: np.ndarray, steps: list[dict], present,
                    groups) -> dict | None:
    """A named backlash (alone or in a group verdict): the held-out p99 once the play itself
    is gone, beyond what the ladder's model on the encoders reaches (``unseen``). The play
    is the ladder's, or, for a play the verdict names beside a hysteresis (the ladder leaves
    it out), the one fitted there on its joints."""
    named = set(present) | {m for g in groups for m in g["members"]}
    if "backlash" not in named or not steps:
        return None
    fitted = steps[-1]["all_params"].get("backlash")
    beside = next((g["play_beside"] for g in groups if g.get("play_beside")), None)
    if fitted is None and beside is None:
        return None
    if fitted is not None:
        play = np.nan_to_num(np.asarray(fitted["play_rad"], dtype=float))
    else:
        play = np.zeros(6)
        on = np.asarray(beside["joints"]) - 1
        play[on] = np.asarray(beside["play_rad"], dtype=float)[on]
    if not play.max() > 0:
        return None         # no play fitted on any joint: nothing to take away
    left, share = unseen.without_play(data, final_pct / 100.0, play)
    p99 = ladder_mod.p99(100.0 * left)
    return {"backlash": {
        "heldout_p99_pct": p99.tolist(),
        "ladder_heldout_p99_pct": steps[-1]["heldout_p99_pct"],
        "play_rad": play.tolist(),
        "travel_rms_share_of_play": share.tolist()}}


def select_plausible(problem: selection.Problem, names: list[str], rng, *, min_gain: float,
                     confidence: float, min_share: float, progress=None):
    """Forward and backward selection among ``names`` (which loses the implausible ones),
    until every family kept fits plausibly. Returns the steps, the selection's information,
    the families kept, the implausible ones (with their checks) and every candidate's
    held-out error alone."""
    implausible = {}
    alone = None
    # A family that explains the data only with physically implausible parameters is not
    # named: selection runs again without it, and its fit is reported (what it absorbed stays
    # in the leftover, where the leftover verdict can place it).
    forced: list[str] = []
    while True:
        steps_found, info = selection.greedy(problem, names, rng, min_gain=min_gain,
                                             confidence=confidence, min_share=min_share,
                                             progress=progress)
        alone = alone or info["alone"]
        kept = [s.added for s in steps_found]
        kept += [n for n in forced if n not in kept and n in names]
        checks = verdicts.plausibility(problem, kept, selection.fit(problem, kept)) \
            if kept else {}
        bad = [n for n in kept if not checks[n]["plausible"]]
        if not bad:
            break
        # An implausible fit may be absorbing a neighbour the forward pass did not reach
        # (assembly errors soaking up elastic links): with that neighbour modelled too, the
        # fit can be plausible and the held-out error lower; then keep both.
        helper = verdicts.rescue(problem, kept, bad, [n for n in names if n not in kept])
        if helper is not None:
            forced.append(helper)
            if progress:
                progress(f"added {helper}: with it, {', '.join(bad)} fit plausibly")
            if set(forced) - set(kept):
                steps_found = selection._rebuild(problem, kept + [helper], info["base"],
                                                 rng, confidence)
                kept = kept + [helper]
                break
        # One at a time, the furthest out of bounds first: in a joint fit, a family that
        # soaks up what none of them describes can push its neighbours out of bounds too;
        # without it they may fit plausibly.
        worst = verdicts.furthest_out_of_bounds(checks, bad)
        implausible[worst] = checks[worst]
        names.remove(worst)
        if progress:
            progress(f"not named: {worst} fits only with implausible parameters")
    return steps_found, info, kept, implausible, alone


def _drop(cache) -> None:
    if cache is not None:
        cache.path.unlink(missing_ok=True)


def _decide(data, problem, terms, skipped, where, baseline_p99, cache, started, *, seed,
            progress, min_gain, confidence, min_share, first: Selected | None = None,
            scratch=None) -> dict:
    """``first``: this problem's selection when it is already made (:func:`selected`);
    ``scratch``: a directory where the ladder's held-out predictions wait (long logs)."""
    design = data.design
    names = [t.name for t in terms]
    if first is None:
        first = selected(problem, names, seed, min_gain=min_gain, confidence=confidence,
                         min_share=min_share, progress=progress)
    rng = first.rng()
    steps_found, info, kept, implausible, alone = (first.steps, first.info, list(first.kept),
                                                   dict(first.implausible), first.alone)
    base_sse = info["base"]
    group_verdicts = verdicts.groups(problem, kept, info)
    # Members of a group verdict join the ladder (in forward order): the shrink is predicted
    # with every effect the verdict names, whichever of them the log cannot tell apart.
    extra = [n for n in info["forward"] if n not in kept
             and any(n in g["members"] for g in group_verdicts)]
    if extra:
        steps_found = selection._rebuild(problem, kept + extra, base_sse, rng, confidence)
    # A family whose own share is lost in the noise (the error it removes is less than one
    # axis's white noise over the log) is neither named nor kept: at the noise floor any
    # smooth family fits something, and nothing tells its cause from noise or from a
    # neighbouring, unknown effect (whose share it would take from the family that has it).
    ladder_names, faint = verdicts.drop_faint(problem, [s.added for s in steps_found])
    if faint:
        steps_found = selection._rebuild(problem, ladder_names, base_sse, rng, confidence)
        kept = [n for n in kept if n in ladder_names]
        if progress:
            progress("not named, below the noise floor: "
                     + ", ".join(f["name"] for f in faint))
        group_verdicts = verdicts.groups(problem, kept, info,
                                         faint={f["name"] for f in faint})
    floor = verdicts.noise_floor_sse(problem)
    group_verdicts = [g for g in group_verdicts
                      if verdicts.above_noise(g["share_of_gap"] * base_sse.sum(), floor)]

    # Held-out predictions: every candidate alone, and the refit after every ladder step.
    models = {("alone", t.name): (problem.cols([t.name]),
                                  selection.fold_coefficients(problem, [t.name]))
              for t in terms}
    chosen: list[str] = []
    for step in steps_found:
        chosen.append(step.added)
        models[("step", step.added)] = (problem.cols(chosen),
                                        selection.fold_coefficients(problem, chosen))
    held = stream.predict(data, terms, problem.bounds, problem.fold_of_block, models,
                          store={k for k in models if k[0] == "step"}, x_all=problem.x,
                          cache=cache, progress=progress, spill=scratch)

    candidates = []
    for term in terms:
        sse = alone[term.name]
        boot = selection.stratified_gain(base_sse, sse, rng)
        candidates.append({
            "name": term.name,
            "heldout_p99_pct": held["p99"][("alone", term.name)].tolist(),
            "score": selection.gain(base_sse, sse),
            "score_ci": [float(np.quantile(boot, 0.005)), float(np.quantile(boot, 0.995))],
        })
    candidates.sort(key=lambda c: c["score"], reverse=True)

    y = data.residual / data.fs
    weights, step_p99, final_pred, step_sse, refit_p99 = ladder_mod.monotone(
        y, (held["pred"].pop(("step", s.added)).read() for s in steps_found))
    steps = []
    notes: list[str] = []
    chosen = []
    coef_all = np.zeros(0)
    current = float(base_sse.sum())
    for step, weight, p99_after, sse, refit in zip(steps_found, weights, step_p99, step_sse,
                                                   refit_p99):
        chosen.append(step.added)
        coef_all = selection.fit(problem, chosen)
        params = {}
        cols = 0
        for name in chosen:
            term = problem.terms[name]
            width = len(term.param_names)
            params[name] = term.summarize(coef_all[cols:cols + width])
            cols += width
        notes += physics.warnings(step.added, params[step.added],
                                  Params.from_design(design).k)
        steps.append({"added": step.added,
                      "heldout_p99_pct": p99_after.tolist(),
                      # The step's refit alone, undamped: what its parameters give.
                      "refit_heldout_p99_pct": refit.tolist(),
                      "gain": 1.0 - sse / current if current > 0 else 0.0,
                      "gain_lower": step.gain_low,
                      "damping": (1.0 - weight).tolist(),
                      "params": params[step.added], "all_params": params})
        current = sse

    # Each named family's own share of the gap: what taking it out of the final model costs.
    final_sse = selection.heldout_block_sse(problem, chosen).sum() if chosen else 0.0
    for step in steps:
        step["share_of_gap"] = selection.removal_share(problem, chosen, {step["added"]},
                                                       base_sse.sum(), final_sse)
    on_chip = onchip.prediction(data, problem, chosen, progress=progress)
    leftover_fs = np.subtract(y, final_pred, out=final_pred)    # the prediction is not needed
    del y
    base_total = float(base_sse.sum())
    left = float(current)
    # Plausibility of every named family's fit, and of each candidate's fit alone.
    named_plausibility = verdicts.plausibility(problem, chosen, coef_all) if chosen else {}
    for c in candidates:
        c["plausibility"] = verdicts.plausibility(
            problem, [c["name"]], selection.fit(problem, [c["name"]]))[c["name"]]
    left_verdict = leftover.analyse(data, leftover_fs)
    # The leftover's whole-log features (a long log's largest arrays) are not needed again.
    for name in ("smooth_velocity", "_play_cache", "position_mm"):
        data.__dict__.pop(name, None)
    final_pct = 100.0 * leftover_fs
    del leftover_fs
    # When a sizeable structured leftover shows the vocabulary misses something, a family that
    # carries only a small share of the gap is as likely absorbing part of the missing effect
    # as being there, and so is one that explains less than that leftover whatever its size:
    # it stays in the ladder (the correction works) but is not named. What is missing is the
    # leftover beyond the white noise (noise is no missing effect). A family its own
    # signature confirms (backlash's dwell) shows what no absorber shows, and the single best
    # explanation, removing a large share on its own, is none either.
    missing = missing_share(problem, left, base_total) if left_verdict["structured"] else 0.0
    confirmed = {n for n, v in info["signature"].items() if v["confirmed"]}
    traded = group_shares(problem, chosen, base_total, refinements=True) if chosen else {}
    alone_share = {n: selection.gain(base_sse, alone[n]) for n in chosen}
    partial = []
    if chosen and missing > 0:
        partial = partial_families(
            steps, group_shares(problem, chosen, base_total), traded, alone_share, missing,
            confirmed | first_explanation(alone, base_sse, info["forward"], chosen, traded))
    unnamed = {p["name"] for p in partial}
    # A family that carries too little of the gap, with the families it trades with, to
    # tell it from its neighbours' trading is not named either; nor one that carries too
    # little to matter, even where its own signature confirms it (a play of a few counts
    # in a mix whose gap is elsewhere).
    minor = minor_families(steps, traded, alone_share,
                           [n for n in kept if n not in unnamed], confirmed)
    named_rest = [n for n in chosen if n in kept and n not in unnamed
                  and n not in {m["name"] for m in minor}]
    if minor and not named_rest and chosen:
        # Every name would go: families that trade without a declared group (collinear
        # columns) can each carry little while together they carry the gap. Taking them all
        # out of the final model is the test, by the share that struck them: a small name
        # must stand on its own, and a set of small names together as much.
        if names_together(minor, float((base_sse.sum() - final_sse) / base_total)):
            minor = []
    unnamed |= {m["name"] for m in minor}
    # A spring-rate error named beside a stiffening spring may be nothing but the straight
    # part the spring's columns leave out: it is named only with a share beyond that.
    straight = verdicts.straight_parts(
        problem, chosen, [n for n in chosen if n in kept and n not in unnamed])
    unnamed |= {s["name"] for s in straight}
    # A group verdict names its members: none of them is a minor name.
    group_verdicts = [g for g in group_verdicts
                      if not set(g["named_alone"]) & {m["name"] for m in minor}]
    present = [n for n in chosen if n in kept and n not in unnamed]
    # Members of a group named beside a larger one with little of their own say "and/or".
    own = {s["added"]: s["share_of_gap"] for s in steps}
    present, group_verdicts = verdicts.fold_small_members(
        problem, present, chosen, own, group_verdicts, SMALL_SHARE, spared=confirmed)
    present = verdicts.order_refinements(problem, present, chosen, coef_all)
    # Beside a structured leftover (something the model misses), a small name (under
    # PARTIAL_SHARE of the gap) that another family could take the place of, as well, says
    # no more than that family, and it may be soaking up part of what is missing: neither
    # is named (``stand_ins``), unless its own signature confirms it. With a white leftover
    # the model explains the gap. A member of a group verdict is the group's to judge.
    grouped = {m for g in group_verdicts for m in g["members"]}
    small = [n for n in present if n not in confirmed and n not in grouped
             and own[n] < PARTIAL_SHARE]
    found = verdicts.stand_ins(
        problem, chosen, small if missing > 0 else [],
        [n for n in names if n not in chosen and n not in implausible])
    stand_ins = [{"name": name, "share_of_gap": own[name], "stand_ins": others}
                 for name, others in found.items()]
    present = [n for n in present if n not in found]
    if progress and found:
        progress("not named, another family fits as well: " + ", ".join(found))
    # A play of several counts that fits beside a named hysteresis: the log cannot tell it
    # from the loop, which took up its switch (the group verdict says "and/or").
    # (Not a play the noise test struck: that says the log shows nothing of it.)
    beside = verdicts.play_beside(problem, chosen, set(present) | grouped, named_plausibility) \
        if "backlash" not in implausible and "backlash" not in {f["name"] for f in faint} \
        else None
    if beside is not None:
        group_verdicts = verdicts.join_play(problem, chosen, present, group_verdicts, beside)
        if progress:
            progress("a play fits beside the hysteresis: " + group_verdicts[-1]["text"])
    for step in steps:
        step["named"] = step["added"] in present
    beyond = beyond_encoders(data, final_pct, steps, present, group_verdicts)
    result = {
        "baseline_heldout_p99_pct": baseline_p99,
        "present": present,
        "partial": partial,
        "stand_ins": stand_ins,
        "minor": minor,
        "straight_part": straight,
        "below_noise": faint,
        "groups": group_verdicts,
        "ladder": steps,
        "on_chip": on_chip,
        "beyond_encoders": beyond,
        "candidates": candidates,
        "plausibility": named_plausibility,
        "implausible": implausible,
        "signature_tests": info["signature"],
        "excitation": {**excitation.report(problem), "axes": excitation.axes(data, problem)},
        "unexplained": {
            "table_v": gap.percent_table(final_pct),
            "share_of_squared_error": left / base_total if base_total > 0 else 0.0,
            "cross_axis": gap.cross_axis_sensitivity(final_pct / 100.0 * data.fs,
                                                     data.reference, data.fs),
            "verdict": left_verdict,
        },
        "where": where,
        "skipped": skipped,
        "warnings": notes,
        "axes": list(AXES),
        "full_scale": data.fs.tolist(),
        "samples": len(data),
        "settings": {"blocks": problem.n_blocks, "folds": len(problem.folds),
                     "run_blocks": selection.RUN_BLOCKS,
                     "buffer_blocks": selection.BUFFER_BLOCKS, "min_gain": min_gain,
                     "confidence": confidence, "min_share": min_share,
                     "bootstrap": selection.N_BOOT, "seed": seed,
                     # The friction's velocity fit (half width in samples and s, degree).
                     "velocity_fit": {"half_width": data.velocity_window[0],
                                      "half_width_s": data.velocity_window[0] * data.step,
                                      "degree": data.velocity_window[1]}},
        "design": {"name": design.name, "hash": f"0x{design.hash32():08x}"},
        "seconds": time.perf_counter() - started,
    }
    return result
