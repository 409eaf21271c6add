"""What a calibration on the chip should leave: the diagnosis's final model refitted with the
features a board can compute, and only the part a board applies.

The diagnosis explains a log offline: its friction sees the joint speed from a centred fit (two
samples of the future) and its backlash places each reversal across the dwell before the encoder
moved again (a look-ahead). A board has neither: it knows the speed from past counts (a filtered
difference, led by its filtered acceleration) and a reversal once the encoder shows it. And some
effects are not applied on the board at all (``delta6.core.calibration.NOT_APPLIED``), and the
refit treats them as ``delta6 calibrate`` does: the rig's latency is fitted with the rest
(whether or not the ladder has it, in the calibration's first-order form, kept in [0, 0.2 s] on
each fold), so the others are not biased by it, and left in the error; a thermal drift or a
harness is not fitted at all (a calibration cannot follow it), so the applied families take
what they can of it, as on the board. (Fitted beside them and then left out, a harness the
applied families partly cancelled made a development run's forecast 25 % FS on Fx against the
analytical model's 9 %; fitted as the calibration fits, 13 %. The calibration itself, which
also left out families that fitted only implausibly and took others in their place, left 5 % on
its own held-out blocks, where the analytical model had 6 %.)
The held-out p99 of that prediction, with the diagnosis's own folds, is the diagnosis's model
as a board would apply it: a forecast of what a calibration on the chip leaves on a run like
this one (``delta6 calibrate`` fits the same families in the board's own forms, and may add a
family that lowers the held-out error further; ``docs/calibration.md``, "Single-effect
scenarios").
"""
from __future__ import annotations

import numpy as np

from delta6.core.calibration import LATENCY, NOT_APPLIED
from delta6.diagnosis import ladder, selection, stream
from delta6.diagnosis import terms as terms_mod
from delta6.diagnosis.data import GapData

#: The families whose features a board computes differently (the others are causal already).
CAUSAL_FORMS = {
    "joint_friction": "the joint speed from past counts (a filtered difference led by its "
                      "filtered acceleration), not a centred fit",
    "backlash": "each reversal once the encoder shows it, not spread over the dwell before",
}


def bounded_latency(problem: selection.Problem, fitted: list[str], coefs: np.ndarray
                    ) -> np.ndarray:
    """The fold coefficients ``coefs`` (K, c) of ``fitted`` (the latency last) with the
    latency kept in [0, ``terms.LATENCY_LIMIT_S``] as the calibration keeps it: in a fold whose
    fit puts it outside, it is held at the bound it crossed and the others are refitted (a
    quadratic fit with one bounded parameter whose free optimum lies outside has its
    optimum on that bound)."""
    out = np.array(coefs, dtype=float, copy=True)
    others = problem.cols(fitted[:-1])
    lat = problem.cols([LATENCY])
    assert fitted[-1] == LATENCY and len(lat) == 1, fitted
    high = terms_mod.LATENCY_LIMIT_S
    for k, fold in enumerate(problem.folds):
        bound = 0.0 if out[k, -1] < 0.0 else high if out[k, -1] > high else None
        if bound is None:
            continue
        train = selection.train_blocks(problem, fold)
        gram = problem.gram[train].sum(axis=0)
        xty = problem.xty[train].sum(axis=0)
        pen = None if problem.penalty is None else problem.penalty[others]
        out[k, :-1] = selection.solve(gram[np.ix_(others, others)],
                                      xty[others] - bound * gram[others, lat[0]], pen)
        out[k, -1] = bound
    return out


def prediction(data: GapData, problem: selection.Problem, chosen: list[str], *,
               progress=None) -> dict:
    """The held-out p99 (% FS per axis) of the final model ``chosen`` refitted on ``data``'s
    causal view and applied without the families a board does not apply."""
    applied = [n for n in chosen if n not in NOT_APPLIED]
    result = {"families": applied, "not_applied": [n for n in chosen if n in NOT_APPLIED],
              "causal_forms": [n for n in applied if n in CAUSAL_FORMS]}
    if not applied:
        # Nothing a board applies: it leaves the analytical model's error (None: no ladder).
        result["heldout_p99_pct"] = (ladder.baseline_p99(data.residual / data.fs).tolist()
                                     if chosen else None)
        return result
    if progress:
        progress("on the chip: the final model with causal features")
    view = data.causal_view()
    # Fitted as ``delta6 calibrate`` fits: the applied families and the rig's latency (whether
    # or not the ladder has it; a latency the user states, which a log does not tell, is not
    # fitted there), never a thermal drift or a harness, which a calibration cannot follow.
    # The latency in the calibration's form: its first-order column, kept in the rig's range.
    fitted = applied + [LATENCY]
    terms = [terms_mod.first_order_latency() if n == LATENCY else problem.terms[n]
             for n in fitted]
    keep = problem.x is not None
    causal = selection.build_problem(view, terms, keep_columns=keep)
    coefs = bounded_latency(causal, fitted, selection.fold_coefficients(causal, fitted))
    # The fold coefficients are in the order of ``fitted``'s columns.
    order = causal.cols(fitted)
    on_board = np.isin(order, causal.cols(applied))
    held = stream.predict(view, terms, causal.bounds, causal.fold_of_block,
                          {"on_chip": (order[on_board], coefs[:, on_board])}, store=set(),
                          x_all=causal.x, progress=progress)
    result["heldout_p99_pct"] = held["p99"]["on_chip"].tolist()
    return result
