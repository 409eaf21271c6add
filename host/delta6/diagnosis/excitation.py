"""Does the log excite each effect enough to judge it? Per family and joint, from the Gram
summaries alone.

For a parameter c, ``z = prior_sd_c * sqrt(Gram_cc) / sigma`` is how many noise standard
errors the wrench change of a plausible-size parameter stands out by (Gram over the whole log,
sigma the white-noise level of the residual): ``excited`` when z >= 10, ``weak`` when z >= 3,
``not excited`` below. ``fold_support`` is the smallest share of a parameter's excitation
found in the training blocks of any fold, relative to their share of the samples: near 1 when
every fold sees the parameter as the whole log does, near 0 when one fold's training blocks
miss it (the held-out fold would need extrapolation; the physical prior then keeps the
prediction near zero). A log that excites one axis at a time keeps every fold's support up
because the folds interleave (``selection``).
"""
from __future__ import annotations

import re

import numpy as np

from delta6.diagnosis import selection

EXCITED_Z = 10.0
WEAK_Z = 3.0
_JOINT = re.compile(r"(?:^|_)j([1-6])(?:_|$)")


def _joint(param: str) -> str:
    m = _JOINT.search(param)
    return f"j{m.group(1)}" if m else "all"


def report(problem: selection.Problem) -> dict:
    """{family: {joint or "all": {"z", "level", "fold_support"}}} and the families the log
    cannot support at all (no joint excited)."""
    sigma = np.sqrt(max(problem.noise_var, 1e-300))
    diag = np.einsum("bii->bi", problem.gram)              # (B, P)
    total = diag.sum(axis=0)
    samples = np.diff(problem.bounds).astype(float)
    support = np.full(len(total), np.inf)
    for fold in problem.folds:
        train = selection.train_blocks(problem, fold)
        share = samples[train].sum() / samples.sum()
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = diag[train].sum(axis=0) / total / share
        support = np.minimum(support, np.where(total > 0, ratio, 0.0))
    out, unsupported = {}, []
    for name, term in problem.terms.items():
        cols = np.arange(problem.slices[name].start, problem.slices[name].stop)
        prior = (np.asarray(term.prior_sd, float) if term.prior_sd is not None
                 else np.ones(len(cols)))
        z = prior * np.sqrt(total[cols]) / sigma
        groups: dict[str, list[int]] = {}
        for i, param in enumerate(term.param_names):
            groups.setdefault(_joint(param), []).append(i)
        rows = {}
        for joint, idx in groups.items():
            best = int(idx[int(np.argmax(z[idx]))])
            zj = float(z[best])
            rows[joint] = {"z": zj, "level": ("excited" if zj >= EXCITED_Z else
                                              "weak" if zj >= WEAK_Z else "not excited"),
                           "fold_support": float(min(1.0, support[cols[best]]))}
        out[name] = rows
        if all(r["level"] == "not excited" for r in rows.values()):
            unsupported.append(name)
    return {"families": out, "unsupported": unsupported,
            "thresholds": {"excited_z": EXCITED_Z, "weak_z": WEAK_Z}}


def axes(data, problem: selection.Problem) -> dict:
    """How the log loads each axis: the 95th percentile of |reference| / FS over the log, and
    the smallest share of it any fold's training blocks reach."""
    ref = np.abs(data.reference / data.fs)
    whole = np.percentile(ref, 95, axis=0)
    worst = np.full(6, np.inf)
    for fold in problem.folds:
        train = selection.train_blocks(problem, fold)
        rows = np.concatenate([np.arange(problem.bounds[b], problem.bounds[b + 1])
                               for b in train])
        worst = np.minimum(worst, np.percentile(ref[rows], 95, axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(whole > 0, worst / whole, 0.0)
    return {"p95_load_fs": whole.tolist(), "training_share_min": share.tolist()}
