"""Fit a calibration to a calibration log.

1. **Which effects.** The gap diagnosis (``delta6.diagnosis``) names the effects present; the
   correctable ones are taken, then any other correctable family that still lowers the
   time-blocked held-out error of the calibrated model by more than ``MIN_EXTRA_GAIN`` of what
   is left (at the lower 5 % of a block bootstrap) is added: the diagnosis names an effect only
   when it can tell it apart; a calibration may also use a family that merely helps. Or the
   user names the effects (``--effect``). Thermal drift is not corrected.
   The reference sensor's latency is always fitted, as a property of the rig (never applied):
   a late reference and a viscous friction of the opposite sign look nearly alike, and left
   out the latency ends up in the friction (or the user states it, ``rig_latency``).
2. **Held-out check.** ``HELDOUT_BLOCKS`` of the log's ``N_BLOCKS`` time blocks are held out,
   in ``HELDOUT_RUNS`` runs spread over the log, the last one its tail (``heldout_split``; a
   buffer block either side of each run is not trained on); the calibration fitted on the rest
   is scored there: the Table V before (analytical model) and after (calibrated model) in the
   file. Spread, not one tail: a log that loads one axis at a time (weights hung axis by axis,
   the paper's Fig. 9) would otherwise hold out an axis its training never loaded, and score
   an extrapolation. An axis the calibrated model leaves worse than the analytical one there
   gets a note.
3. **The fit.** Gauss-Newton on the calibrated model itself: the columns (``families``) are
   the model's first-order response around the analytical model; each iteration solves the
   normal equations for the residual of the *nonlinear* calibrated model (FS-normalised, all
   six axes) and updates the calibration. Then the final calibration is fitted on all blocks.
   The parameters carry the diagnosis's physical priors (``Term.prior_sd``: a Gaussian prior
   on the calibration's values, not on the step, so a direction the log hardly excites, such
   as a + b of a branch, stays near zero instead of drifting with every iteration).
4. **Signs physics fixes.** The rig's latency lies in [0, ``MAX_RIG_LATENCY_S``]; a family
   may hold signs too (``Family.constraints``: friction opposes the motion). Each step is the
   prior-regularised least squares under those inequalities (``bounded.solve``).
5. **Plausibility.** A family whose fitted parameters leave the diagnosis term's plausible
   limits (``Term.plausibility``) or the file's bounds, or a curve beyond the board's int16
   tables (``families.curve_table_checks``; the iterates hold it at the tables' range, so the
   model stays defined while the fit runs), is left out (the worst first) and the
   rest refitted; the calibration and the report say so (``fit.left_out``). An implausible
   calibration is never written.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from delta6 import __version__
from delta6.calibration import bounded
from delta6.calibration.families import (
    Context,
    curve_table_checks,
    families,
    without_vanishing_curves,
)
from delta6.core import accuracy
from delta6.core.calibrated import (
    CalibratedModel,
    counts_from_angles,
    periods_between,
    sample_period,
)
from delta6.core.calibration import CORRECTED, LATENCY, NOT_APPLIED, Calibration, new_settings
from delta6.core.design import Design
from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.diagnosis import selection
from delta6.diagnosis.data import GapData
from delta6.diagnosis.run import diagnose_data
from delta6.diagnosis.terms import LATENCY_LIMIT_S, TERMS, Term, first_order_latency

N_BLOCKS = 40
HELDOUT_BLOCKS = 8
HELDOUT_RUNS = 4
MIN_EXTRA_GAIN = 0.01
EXTRA_CONFIDENCE = 0.95
ITERATIONS = 3
FINAL_ITERATIONS = 2


#: The largest rig latency the fit accepts: the diagnosis's plausible limit.
MAX_RIG_LATENCY_S = LATENCY_LIMIT_S


@dataclass
class CalibrationFit:
    calibration: Calibration
    heldout_before: dict          # Table V of the analytical model on the held-out blocks
    heldout_after: dict           # ... of the calibrated model (latency not applied)
    latency_s: float              # the rig's (fitted, or as given)
    heldout_before_rig: dict | None = None    # both against the reference advanced by it
    heldout_after_rig: dict | None = None
    latency_given: bool = False   # stated by the user, not fitted
    diagnosis: dict | None = None
    chosen_by: str = "diagnosis"
    seconds: float = 0.0
    notes: list = field(default_factory=list)


def _terms(ctx: Context, fams: dict) -> list[Term]:
    out = []
    for name, fam in fams.items():
        out.append(Term(name, "calibration", fam.param_names, "",
                        lambda d, fam=fam: fam.columns(ctx), prior_sd=fam.prior_sd))
    return out


def _table(err_pct: np.ndarray) -> dict:
    t = accuracy.table(err_pct, (95, 99, 100))
    return {"p95_pct": t["p95"], "p99_pct": t["p99"], "max_pct": t["p100"]}


def _heldout_tables(data: GapData, calibrated: np.ndarray, rows: np.ndarray, latency: float):
    """Table V of the analytical and the calibrated model on the held-out ``rows``: against
    the recorded reference, and against the reference advanced by the rig's ``latency``."""
    before = _table(data.residual_pct[rows])
    after = _table((100.0 * (calibrated - data.reference) / data.fs)[rows])
    advanced, keep = accuracy.advanced(data.t, data.reference, latency)
    # Time increases, so the samples with a later reference are the log's first ones:
    # ``advanced`` is indexed like the log.
    held = rows[keep[rows]]
    reference = advanced[held]
    before_rig = _table(100.0 * (data.model[held] - reference) / data.fs)
    after_rig = _table(100.0 * (calibrated[held] - reference) / data.fs)
    return before, after, before_rig, after_rig


class _Fitter:
    """The problem (columns of every family, FS-normalised, with per-block Gram matrices) and
    the Gauss-Newton iterations on a chosen subset."""

    def __init__(self, data: GapData, settings: Calibration, progress):
        self.data = data
        self.counts = counts_from_angles(data.theta)
        self.dt = sample_period(data.t)
        self.periods = periods_between(data.t, self.dt)
        self.settings = settings
        terms, _ = CalibratedModel(data.design, settings, saturate_curves=True).joint_terms(
            self.counts, self.dt, periods=self.periods)
        self.speed = terms.speed
        self.families = families(settings, data.design)
        ctx = Context(data, terms, settings)
        all_terms = _terms(ctx, self.families) + [first_order_latency()]
        # The families' columns come from the calibrated model run over the whole log (its
        # history state included), so the log is one piece.
        self.problem = selection.build_problem(data, all_terms, n_blocks=N_BLOCKS,
                                               progress=progress, piece_samples=len(data))

    def speed_reached(self, rows) -> np.ndarray:
        """Per joint, the fastest the board's joint speed went over ``rows``: how far the
        friction fitted there is known (``Calibration.friction_speed_limit_rad_s``)."""
        return np.abs(self.speed[rows]).max(axis=0)

    def rows(self, blocks) -> np.ndarray:
        b = self.problem.bounds
        return np.concatenate([np.arange(b[i], b[i + 1]) for i in blocks])

    def fit(self, cal: Calibration, names: list[str], blocks, iterations: int,
            latency: float = 0.0) -> tuple[Calibration, float]:
        p = self.problem
        cols = p.cols(names)
        if len(cols) == 0:
            return cal, latency
        previous = (cal, latency)
        gram = p.gram[np.ix_(blocks, cols, cols)].sum(axis=0)
        penalty = p.penalty[cols]
        rows = self.rows(blocks)
        x = p.x[rows][:, :, cols].reshape(-1, len(cols))
        fs = self.data.fs
        for _ in range(iterations):
            with np.errstate(invalid="ignore", over="ignore"):
                pred = self.predict(cal, latency)
            if not np.isfinite(pred).all():
                # A step left the model's domain (the trilateration's square root, a curve's
                # table): the iterate before it is the fit; its plausibility is judged next.
                return previous
            previous = (cal, latency)
            r = ((self.data.reference - pred) / fs)[rows].reshape(-1)
            # The prior is on the values (current + step), so it pulls them, not the step,
            # towards zero: (G + P) step = X^T r - P current.
            current = np.concatenate([[latency] if n == LATENCY
                                      else self.families[n].values(cal) for n in names])
            a, lower = self.constraints(cal, names)
            # The constraints on the step: A (current + step) >= lower. Start from no step,
            # or, if the current values break a constraint, from the neutral ones.
            lower = lower - a @ current
            start = np.zeros(len(current)) if np.all(lower <= 0) else -current
            step = bounded.solve(gram + np.diag(penalty), x.T @ r - penalty * current,
                                 a, lower, start)
            if not np.isfinite(step).all():
                return previous
            at = 0
            for name in names:
                width = p.slices[name].stop - p.slices[name].start
                part = step[at:at + width]
                at += width
                if name == LATENCY:
                    # The solver reaches an active bound only to within rounding (-7e-18).
                    latency = min(max(latency + float(part[0]), 0.0), MAX_RIG_LATENCY_S)
                else:
                    cal = self.families[name].apply(cal, part)
        return cal, latency

    def constraints(self, cal: Calibration, names) -> tuple[np.ndarray, np.ndarray]:
        """The fitted parameters' inequalities, A @ values >= lower, over ``names``' columns."""
        widths = [self.problem.slices[n].stop - self.problem.slices[n].start for n in names]
        rows, lowers, at = [], [], 0
        for name, width in zip(names, widths):
            if name == LATENCY:
                a, lower = np.array([[1.0], [-1.0]]), np.array([0.0, -MAX_RIG_LATENCY_S])
            elif self.families[name].constraints is not None:
                a, lower = self.families[name].constraints(cal)
            else:
                at += width
                continue
            block = np.zeros((len(a), sum(widths)))
            block[:, at:at + width] = a
            rows.append(block)
            lowers.append(lower)
            at += width
        if not rows:
            return np.zeros((0, sum(widths))), np.zeros(0)
        return np.concatenate(rows), np.concatenate(lowers)

    def predict(self, cal: Calibration, latency: float = 0.0) -> np.ndarray:
        """What the reference should read: the calibrated wrench, late by the rig's latency."""
        # An iterate's curve may leave the board's tables: held at their range here, it is
        # left out as implausible after the fit (``_worst_implausible``).
        w, _ = CalibratedModel(self.data.design, cal, saturate_curves=True).run(
            self.counts, self.dt, periods=self.periods)
        if latency:
            w = w - latency * np.gradient(w, self.data.t, axis=0)
        return w


#: The friction's speed limit as fitted: at least this (a joint that never moved), at most the
#: calibration file's bound.
MIN_SPEED_LIMIT_RAD_S = 1e-6
MAX_SPEED_LIMIT_RAD_S = 100.0


def with_speed_limit(cal: Calibration, reached: np.ndarray) -> Calibration:
    """``cal`` with its friction held beyond the speeds its log ``reached`` (rad/s per joint),
    when it corrects a friction: a slope fitted on slow motion is not extrapolated to fast.
    Without a friction the speed's lead goes too (it would change nothing but the hash)."""
    if "joint_friction" not in cal.effects:
        return cal.with_(speed_lead_s=0.0)
    # A joint that never moved holds its friction at rest (0 would mean no limit); the
    # file's bound caps a log's glitches.
    return cal.with_(friction_speed_limit_rad_s=np.clip(np.asarray(reached, dtype=float),
                                                        MIN_SPEED_LIMIT_RAD_S,
                                                        MAX_SPEED_LIMIT_RAD_S))


def heldout_split(n_blocks: int = N_BLOCKS, held_blocks: int = HELDOUT_BLOCKS,
                  runs: int = HELDOUT_RUNS) -> tuple[np.ndarray, np.ndarray]:
    """(held-out blocks, training blocks): ``runs`` runs of ``held_blocks / runs`` blocks, each
    at the end of its share of the log (the last one the log's tail), and the blocks more than
    ``selection.BUFFER_BLOCKS`` from any of them."""
    width = held_blocks // runs
    ends = np.linspace(0, n_blocks, runs + 1).astype(int)[1:]
    held = np.concatenate([np.arange(end - width, end) for end in ends])
    blocks = np.arange(n_blocks)
    near = np.abs(blocks[:, None] - held[None, :]).min(axis=1) <= selection.BUFFER_BLOCKS
    return held, blocks[~near]


#: A held-out axis counts as made worse beyond this (relative, and absolute in % FS): the
#: ladder's own resolution (``docs/diagnosis.md``).
WORSE_REL, WORSE_ABS_PCT = 0.02, 0.005


def worse_axes(before: dict, after: dict) -> list[str]:
    """Notes, one per axis whose held-out p99 the calibrated model leaves worse than the
    analytical one."""
    b, a = np.asarray(before["p99_pct"]), np.asarray(after["p99_pct"])
    return [f"held-out {axis}: the calibrated model's p99 is {a[i]:.2f} % FS against the "
            f"analytical model's {b[i]:.2f}: the log may not load that axis enough, or in a "
            "way the rest of it does not; check the calibration on another run (delta6 "
            "evaluate) before using it"
            for i, axis in enumerate(AXES)
            if a[i] > b[i] * (1.0 + WORSE_REL) + WORSE_ABS_PCT]


def _extend(fitter: _Fitter, chosen: list[str], rng, progress) -> list[str]:
    """Add correctable families that still lower the held-out error (module docstring). The
    rig's latency is not in these trials: their linear fits are unbounded, and a negative
    latency would pass for the friction a candidate brings."""
    p = fitter.problem
    chosen = list(chosen)
    current = selection.heldout_block_sse(p, chosen)
    while True:
        remaining = [f for f in fitter.families if f not in chosen]
        if not remaining:
            return chosen
        trials = {f: selection.heldout_block_sse(p, chosen + [f]) for f in remaining}
        best = max(trials, key=lambda f: selection.gain(current, trials[f]))
        boot = selection.bootstrap_gain(current, trials[best], rng, n_boot=1000)
        low = float(np.quantile(boot, 1.0 - EXTRA_CONFIDENCE))
        if low <= MIN_EXTRA_GAIN:
            return chosen
        if progress:
            progress(f"calibration also uses {best} (beyond the diagnosis's verdict): held-out "
                     f"error -{100 * selection.gain(current, trials[best]):.1f} %")
        chosen.append(best)
        current = trials[best]


def _anti_dissipative(cal: Calibration) -> list[str]:
    """A note when the fitted hysteresis loops run the wrong way on most joints (negative
    weights: a loop that gives energy back). The weights stay free (they carry what the causal
    backlash switch and the lagging speed estimate miss, and lower the held-out error), but
    such a family corrects a lag, not a spring's hysteresis, and the file says so."""
    if "spring_hysteresis" not in cal.effects:
        return []
    loops = np.asarray(cal.hysteresis_nm, float).sum(axis=1)
    backwards = [j + 1 for j in range(6) if loops[j] < 0]
    if len(backwards) <= 3:
        return []
    return [f"spring_hysteresis: the fitted loops run backwards (negative weights) on joints "
            f"{', '.join(map(str, backwards))}: the family corrects a lag the other terms leave "
            "(friction's or backlash's causal switch), not a spring's hysteresis"]


def _worst_implausible(fitter: _Fitter, cal: Calibration, chosen) -> tuple | None:
    """The chosen family furthest out of its plausible bounds (or, a curve, out of the board's
    tables), with its failed checks (None: every family is plausible)."""
    worst, worst_ratio = None, 1.0
    for effect in chosen:
        failed = fitter.families[effect].implausible(cal) + [
            c for c in curve_table_checks(fitter.data.design, cal, effect) if c["ratio"] > 1.0]
        ratio = max((c["ratio"] for c in failed), default=0.0)
        if ratio > worst_ratio:
            worst, worst_ratio = (effect, failed), ratio
    return worst


def _why_out(checks) -> str:
    """Physics or format: a curve beyond the board's int16 tables, or a value beyond the
    calibration file's bounds, is no implausible effect."""
    kinds = {"board" if c["quantity"].startswith("board_table") else
             "file" if c["quantity"].startswith("file_bounds") else "physics" for c in checks}
    if kinds == {"board"}:
        return "it needs more than the board's curve tables hold"
    if kinds == {"file"}:
        return "it fits only beyond the calibration file's bounds"
    return "it fits only out of plausible bounds"


def _describe(checks) -> str:
    return "; ".join(f"{c['quantity']} {c['largest']:.3g} > {c['limit']:.3g}"
                     if np.isfinite(c["largest"]) else c["quantity"] for c in checks)


def check_effects(effects) -> None:
    for e in effects:
        if e in NOT_APPLIED and e != LATENCY:
            raise UserError(f"{e} cannot be corrected on the device: {NOT_APPLIED[e]}")
        if e not in CORRECTED and e != LATENCY:
            raise UserError(f"unknown effect {e!r} (one of {', '.join(CORRECTED)})")


def check_rig_latency(value) -> float:
    """A stated rig latency in seconds: finite, in [0, MAX_RIG_LATENCY_S]."""
    try:
        latency = float(value)
    except (TypeError, ValueError):
        raise UserError(f"the rig latency must be a number of seconds, got {value!r}") from None
    if not (np.isfinite(latency) and 0.0 <= latency <= MAX_RIG_LATENCY_S):
        raise UserError(f"the rig latency must be 0..{MAX_RIG_LATENCY_S:g} s (the reference "
                        f"is late, never early), got {value!r}")
    return latency


def effects_to_fit(diagnosis: dict) -> list[str]:
    """The diagnosis's named effects, and those it names only in a wider statement: group
    members it folded into a group verdict (named "and/or", little of their own beside a
    larger member, `verdicts.fold_small_members`), each after the member its group names
    alone, and a spring-rate error that is a stiffening spring's straight part
    (`verdicts.straight_parts`), after the spring: the spring's curve leaves its straight
    part out by construction, so the rate correction carries it. The calibration fits each of
    them as when it was named alone."""
    present = list(diagnosis["present"])
    for g in diagnosis["groups"]:
        lead = [n for n in present if n in g["named_alone"]]
        at = present.index(lead[-1]) + 1 if lead else len(present)
        present[at:at] = [m for m in g.get("folded", []) if m not in present]
    for sp in diagnosis.get("straight_part", []):
        if sp["name"] not in present:
            of = sp["straight_part_of"]
            at = present.index(of) + 1 if of in present else len(present)
            present.insert(at, sp["name"])
    return present


#: Families whose columns leave their straight-line part to another (``Term.refines``): the
#: spring's curve is fitted with the rate that carries its straight part.
STRAIGHT_PART_OF = {t.name: t.refines for t in TERMS if t.straight_part is not None}


def with_straight_parts(effects: list[str]) -> list[str]:
    """``effects`` with, after each family that leaves its straight part out, the family
    that carries it (``--effect nonlinear_spring`` fits the spring's rate too: its curve
    alone is not a spring)."""
    out = []
    for e in effects:
        out.append(e)
        carrier = STRAIGHT_PART_OF.get(e)
        if carrier is not None and carrier not in effects and carrier not in out:
            out.append(carrier)
    return out


def calibrate(log, design: Design, *, effects=None, name: str | None = None,
              source: str = "", settings: Calibration | None = None, seed: int = 0,
              rig_latency_s: float | None = None, progress=None) -> CalibrationFit:
    """Fit a calibration of ``design`` to ``log`` (a ``LogData``). ``effects``: the effects
    to correct (None: the diagnosis's findings, extended; see the module docstring).
    ``rig_latency_s``: the rig's known latency (0: none), used instead of fitting it."""
    started = time.perf_counter()
    given = rig_latency_s is not None
    if given:
        rig_latency_s = check_rig_latency(rig_latency_s)
        if effects is not None and LATENCY in effects:
            raise UserError("a stated rig latency is not fitted: drop --effect sensor_latency")
    data = GapData.from_log(log, design)
    base = settings or new_settings(design)
    diagnosis = None
    notes = []
    if effects is None:
        diagnosis = diagnose_data(data, seed=seed, progress=progress)
        present = effects_to_fit(diagnosis)
        chosen = [e for e in present if e in CORRECTED]
        notes += [f"{e}: {NOT_APPLIED[e]}" for e in present if e in NOT_APPLIED
                  and not (e == LATENCY and given)]
        if LATENCY in present and given:
            notes.append(f"{LATENCY}: a property of the calibration rig, given as "
                         f"{1e3 * rig_latency_s:g} ms (--rig-latency), not applied")
        chosen_by = "diagnosis"
    else:
        check_effects(effects)
        chosen = with_straight_parts([e for e in dict.fromkeys(effects) if e in CORRECTED])
        chosen_by = "--effect"
    if progress:
        progress("calibration columns")
    fitter = _Fitter(data, base, progress)
    if effects is None:
        chosen = _extend(fitter, chosen, np.random.default_rng(seed), progress)
    held, train = heldout_split()
    left_out = {}
    while True:
        names = chosen + ([] if given else [LATENCY])
        if progress:
            progress("fitting on the training blocks")
        start = base.with_(effects=tuple(chosen))
        cal, latency = fitter.fit(start, names, train, ITERATIONS,
                                  rig_latency_s if given else 0.0)
        bad = _worst_implausible(fitter, cal, chosen)
        if bad is None:
            rows = fitter.rows(held)
            # What the board gives: no latency, the friction held at the training's speeds.
            calibrated = fitter.predict(with_speed_limit(cal, fitter.speed_reached(
                fitter.rows(train))))
            before, after, before_rig, after_rig = _heldout_tables(
                data, calibrated, rows, latency)
            if progress:
                progress("fitting on all blocks")
            cal, latency = fitter.fit(cal, names, np.arange(N_BLOCKS), FINAL_ITERATIONS,
                                      latency)
            bad = _worst_implausible(fitter, cal, chosen)
        if bad is None:
            break
        effect, checks = bad
        left_out[effect] = checks
        chosen.remove(effect)
        note = f"{effect}: left out, {_why_out(checks)} ({_describe(checks)})"
        notes.append(note)
        if progress:
            progress(note)
    notes += worse_axes(before, after) + _anti_dissipative(cal)
    cal = with_speed_limit(cal, fitter.speed_reached(np.arange(len(data))))
    seconds = time.perf_counter() - started
    fit_record = {
        "log": source, "samples": len(data), "duration_s": float(data.t[-1] - data.t[0]),
        "rate_hz": 1.0 / sample_period(data.t), "created_by": f"delta6 {__version__} calibrate",
        "effects_chosen_by": chosen_by,
        "diagnosis_present": list(diagnosis["present"]) if diagnosis else [],
        # ... and what it names only in a group's "and/or" or as a spring's straight part.
        "diagnosis_effects": effects_to_fit(diagnosis) if diagnosis else [],
        "heldout": f"{HELDOUT_BLOCKS} of {N_BLOCKS} time blocks in {HELDOUT_RUNS} runs "
                   "spread over the log, the last its tail (a buffer block either side); "
                   "the parameters below are refitted on the whole log",
        "not_applied": notes,
        "left_out": sorted(left_out),
        "seconds": round(seconds, 2),
        "heldout_before": before, "heldout_after": after,
        # The same against the reference read the rig's latency later (what the sensor felt
        # at the sample's time): the calibrated wrench is not late, the recorded reference is.
        "heldout_before_rig": before_rig, "heldout_after_rig": after_rig,
    }
    fit_record["rig_latency_s"] = latency
    fit_record["rig_latency"] = "given" if given else "fitted"
    cal = without_vanishing_curves(design, cal).with_(name=name or base.name, fit=fit_record)
    return CalibrationFit(calibration=cal, heldout_before=before, heldout_after=after,
                          heldout_before_rig=before_rig, heldout_after_rig=after_rig,
                          latency_s=latency, latency_given=given, diagnosis=diagnosis,
                          chosen_by=chosen_by, seconds=seconds, notes=notes)
