"""What a calibration on the chip should leave: the diagnosis's final model refitted with the
features a board can compute, and only the part a board applies.

The diagnosis explains a log offline: its friction sees the joint speed from a centred fit (two
samples of the future) and its backlash places each reversal across the dwell before the encoder
moved again (a look-ahead). A board has neither: it knows the speed from past counts (a filtered
difference, led by its filtered acceleration) and a reversal once the encoder shows it. And some
effects are not applied on the board at all (``delta6.core.calibration.NOT_APPLIED``: the rig's
latency, a thermal drift, a harness): they are fitted with the rest, so the others are not
biased by them, and left in the error. The held-out p99 of that prediction, with the diagnosis's
own folds, is the diagnosis's model as a board would apply it: a forecast of what a calibration
on the chip leaves on a run like this one (``delta6 calibrate`` fits the same families in the
board's own forms, and may add a family that lowers the held-out error further;
``docs/calibration.md``, "Single-effect scenarios").
"""
from __future__ import annotations

import numpy as np

from delta6.core.calibration import NOT_APPLIED
from delta6.diagnosis import ladder, selection, stream
from delta6.diagnosis.data import GapData

#: The families whose features a board computes differently (the others are causal already).
CAUSAL_FORMS = {
    "joint_friction": "the joint speed from past counts (a filtered difference led by its "
                      "filtered acceleration), not a centred fit",
    "backlash": "each reversal once the encoder shows it, not spread over the dwell before",
}


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
    terms = [problem.terms[n] for n in chosen]
    keep = problem.x is not None
    causal = selection.build_problem(view, terms, keep_columns=keep)
    coefs = selection.fold_coefficients(causal, chosen)
    # The fold coefficients are in the order of ``chosen``'s columns.
    order = causal.cols(chosen)
    on_board = np.isin(order, causal.cols(applied))
    held = stream.predict(view, terms, causal.bounds, causal.fold_of_block,
                          {"on_chip": (order[on_board], coefs[:, on_board])}, store=set(),
                          x_all=causal.x, progress=progress)
    result["heldout_p99_pct"] = held["p99"]["on_chip"].tolist()
    return result
