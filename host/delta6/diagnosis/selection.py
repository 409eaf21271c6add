"""Which effects are present: time-blocked held-out scoring, a block bootstrap, and greedy
forward selection.

The log is cut into contiguous time blocks; the blocks are grouped into short runs, and the
runs are dealt to the folds in turn, so that every fold holds pieces from all over the log (a
log that excites one axis at a time, as in the paper's Fig. 9, still leaves every axis in the
training blocks of every fold). A term set is fitted on the blocks outside a fold (minus one
buffer block on each side of each of its runs, so history features cannot leak across the
boundary) and scored on the fold. Every term is linear in its parameters, so each block is
summarised once by its Gram matrix X^T X, X^T y and y^T y over the columns of *all* candidate
terms (built piece by piece, ``stream``): any fit and any held-out error is a small dense solve.

Fits are regularised by physics: each parameter has a prior scale (``Term.prior_sd``, the size
the effect plausibly has), and the normal equations get the matching Gaussian prior, noise
variance / scale^2 on the diagonal. A well-excited parameter does not notice it; a parameter
the training blocks hardly excite stays near zero instead of extrapolating.

An effect is called present when two things hold:

1. forward: adding it lowers the held-out squared error by more than ``min_gain`` of what is
   left, at the ``1 - confidence`` lower quantile of a bootstrap over held-out blocks (blocks,
   not samples, are resampled because neighbouring samples are correlated; the loud blocks,
   the fewest that hold half the error left, are resampled among themselves, so that an
   effect living in a few of them, as a latency does in the fast moves between the axes of
   a log that pushes one axis at a time, is not lost to resamples that miss them). Fitting noise
   alone gives gains near zero or negative: a term fitted to data it cannot explain only adds
   variance on held-out blocks;
2. backward: taking it out of the final model raises the held-out squared error by at least
   ``min_share`` of the analytical model's. A family never matches a real effect exactly, and
   a neighbouring family can soak up a little of what the true one misses; this test keeps
   such passengers out of the verdict while keeping a genuine second effect, which carries
   its own share of the error.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from delta6.diagnosis import stream
from delta6.diagnosis.data import GapData
from delta6.diagnosis.leftover import noise_sd
from delta6.diagnosis.terms import Term

N_BLOCKS = 60
N_FOLDS = 5
#: Contiguous blocks per run; runs are dealt to the folds in turn.
RUN_BLOCKS = 3
BUFFER_BLOCKS = 1
MIN_GAIN = 0.02
MIN_SHARE = 0.01
CONFIDENCE = 0.99
N_BOOT = 2000
RIDGE = 1e-9


@dataclass
class Problem:
    """Everything the selection needs, FS-normalised (each axis divided by its full scale)."""

    y: np.ndarray | None          # (n, 6) residual / FS (None: not kept, a long log)
    x: np.ndarray | None          # (n, 6, P) term columns / FS (None: not kept)
    slices: dict                  # term name -> slice of P
    terms: dict                   # term name -> Term
    bounds: np.ndarray            # (B + 1,) sample index of block edges
    gram: np.ndarray              # (B, P, P)
    xty: np.ndarray               # (B, P)
    yty: np.ndarray               # (B,)
    folds: list = field(default_factory=list)   # list of arrays of block indices
    #: Prior precision per column (noise variance / prior scale^2; 0: no prior).
    penalty: np.ndarray | None = None
    #: Signature subsets: name -> (gram, xty, yty, samples) per block over those samples only.
    sub: dict = field(default_factory=dict)
    #: Estimated white-noise variance of one FS-normalised residual value.
    noise_var: float = 0.0

    @property
    def n_blocks(self) -> int:
        return len(self.yty)

    @property
    def fold_of_block(self) -> np.ndarray:
        out = np.empty(self.n_blocks, dtype=int)
        for k, fold in enumerate(self.folds):
            out[fold] = k
        return out

    def cols(self, names) -> np.ndarray:
        return np.concatenate([np.arange(self.slices[n].start, self.slices[n].stop)
                               for n in names]) if names else np.zeros(0, dtype=int)


def make_folds(n_blocks: int, n_folds: int = N_FOLDS, run: int = RUN_BLOCKS) -> list:
    """Block indices of each fold: runs of ``run`` contiguous blocks dealt to the folds in
    turn (with too few blocks for that, contiguous folds)."""
    if n_blocks < n_folds * run * 2:
        return np.array_split(np.arange(n_blocks), n_folds)
    runs = np.array_split(np.arange(n_blocks), n_blocks // run)
    return [np.concatenate(runs[k::n_folds]) for k in range(n_folds)]


def noise_variance(residual: np.ndarray, fs=1.0) -> float:
    """White-noise variance of one FS-normalised residual value (``residual / fs``), from the
    median absolute first difference (slow, structured parts of the residual hardly change
    from one sample to the next; white noise doubles its variance in a difference)."""
    return float(np.mean(noise_sd(residual, fs) ** 2))


def build_problem(data: GapData, terms: list[Term], n_blocks: int = N_BLOCKS,
                  n_folds: int = N_FOLDS, progress=None, keep_columns: bool = True,
                  signatures: dict | None = None, cache=None,
                  piece_samples: int | None = None) -> Problem:
    """The per-block Gram summaries of all ``terms`` (one streamed pass over the log). With
    ``keep_columns`` the columns and the residual are kept too (short logs: per-sample
    predictions with :func:`heldout_prediction`); without, memory stays bounded (``cache``, a
    ``stream.ColumnCache``, keeps them on disk for a later pass). ``piece_samples``: see
    ``stream.accumulate`` (default: its bounded piece)."""
    slices, start = {}, 0
    for term in terms:
        slices[term.name] = slice(start, start + len(term.param_names))
        start += len(term.param_names)
    bounds = np.linspace(0, len(data), n_blocks + 1).astype(int)
    gram, xty, yty, sub, x = stream.accumulate(data, terms, bounds, signatures,
                                               keep_columns=keep_columns, cache=cache,
                                               progress=progress,
                                               piece_samples=piece_samples or stream.PIECE_SAMPLES)
    noise = noise_variance(data.residual, data.fs)
    penalty = np.zeros(start)
    for term in terms:
        if term.prior_sd is not None:
            penalty[slices[term.name]] = noise / np.asarray(term.prior_sd, float) ** 2
    return Problem(y=data.residual / data.fs if keep_columns else None, x=x, slices=slices,
                   terms={t.name: t for t in terms}, bounds=bounds, gram=gram, xty=xty,
                   yty=yty, folds=make_folds(n_blocks, n_folds), penalty=penalty, sub=sub,
                   noise_var=noise)


def solve(gram: np.ndarray, xty: np.ndarray, penalty: np.ndarray | None = None) -> np.ndarray:
    """Least squares from normal equations, scaled for conditioning, with the prior precision
    ``penalty`` on the diagonal and a tiny ridge that only matters for exactly collinear
    columns (geometry parameters some poses cannot separate)."""
    if len(xty) == 0:
        return np.zeros(0)
    gram = gram if penalty is None else gram + np.diag(penalty)
    scale = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    g = gram / np.outer(scale, scale)
    g[np.diag_indices_from(g)] += RIDGE * max(1.0, np.trace(g) / len(g))
    return np.linalg.solve(g, xty / scale) / scale


def train_blocks(problem: Problem, fold: np.ndarray) -> np.ndarray:
    """The blocks a fold is predicted from: all but the fold's and their neighbours."""
    blocks = np.arange(problem.n_blocks)
    near = np.abs(blocks[:, None] - np.asarray(fold)[None, :]).min(axis=1) <= BUFFER_BLOCKS
    return blocks[~near]


def fit(problem: Problem, names, blocks=None) -> np.ndarray:
    cols = problem.cols(names)
    blocks = np.arange(problem.n_blocks) if blocks is None else blocks
    g = problem.gram[np.ix_(blocks, cols, cols)].sum(axis=0) if len(cols) else np.zeros((0, 0))
    v = problem.xty[np.ix_(blocks, cols)].sum(axis=0) if len(cols) else np.zeros(0)
    pen = None if problem.penalty is None else problem.penalty[cols]
    return solve(g, v, pen)


def fold_coefficients(problem: Problem, names) -> np.ndarray:
    """The coefficients each fold is predicted with, (K, c)."""
    return np.array([fit(problem, names, train_blocks(problem, fold))
                     for fold in problem.folds]).reshape(len(problem.folds), -1)


def heldout_block_sse(problem: Problem, names, coefs: np.ndarray | None = None,
                      subset: str | None = None) -> np.ndarray:
    """Held-out squared error of every block, (B,), each block predicted by the fit on the
    blocks outside its fold (or by the given per-fold ``coefs``); over a signature's samples
    only with ``subset``."""
    cols = problem.cols(names)
    gram, xty, yty = ((problem.gram, problem.xty, problem.yty) if subset is None
                      else problem.sub[subset][:3])
    sse = yty.copy()
    if len(cols) == 0:
        return sse
    coefs = fold_coefficients(problem, names) if coefs is None else coefs
    for fold, coef in zip(problem.folds, coefs):
        for b in fold:
            g = gram[b][np.ix_(cols, cols)]
            sse[b] = yty[b] - 2 * coef @ xty[b, cols] + coef @ g @ coef
    return sse


def removal_share(problem: Problem, model, out, base: float, full: float | None = None
                  ) -> float:
    """What taking the families ``out`` out of the model ``model`` costs: the rise of the
    held-out squared error, as a share of ``base`` (the analytical model's). ``full``: the
    model's own held-out squared error when already known."""
    rest = [n for n in model if n not in out]
    if full is None:
        full = heldout_block_sse(problem, model).sum()
    return float((heldout_block_sse(problem, rest).sum() - full) / base)


def heldout_block_sse_tied(problem: Problem, names, name: str, base: str,
                           per_joint) -> np.ndarray:
    """:func:`heldout_block_sse` of the model ``names`` without the per-joint family ``base``,
    its part carried by ``name`` instead: each of ``name``'s columns of joint j (m per joint,
    joint-major) plus ``per_joint[i]`` times ``base``'s column of joint j. The model's
    columns are linear maps of the problem's, so its Gram summaries are too."""
    keep = [n for n in names if n != base]
    cols = problem.cols(keep)
    own, ref = problem.slices[name], problem.slices[base]
    assert ref.stop - ref.start == 6, base
    per_joint = np.asarray(per_joint, dtype=float)
    m = len(per_joint)
    src = np.unique(np.concatenate([cols, np.arange(ref.start, ref.stop)]))
    where = {c: i for i, c in enumerate(src)}
    a = np.zeros((len(src), len(cols)))
    a[[where[c] for c in cols], np.arange(len(cols))] = 1.0
    for k, c in enumerate(cols):
        if own.start <= c < own.stop:
            joint, i = divmod(c - own.start, m)
            a[where[ref.start + joint], k] = per_joint[i]
    # a^T G a per block, as two matrix products: one einsum over the four indices would
    # loop over all of them at once (minutes for a mix with a few hundred columns).
    gram = a.T @ problem.gram[:, src[:, None], src[None, :]] @ a
    tied = replace(problem, y=None, x=None, slices={"tied": slice(0, len(cols))},
                   gram=gram, xty=problem.xty[:, src] @ a, sub={},
                   penalty=None if problem.penalty is None else problem.penalty[cols])
    return heldout_block_sse(tied, ["tied"])


def heldout_prediction(problem: Problem, names) -> np.ndarray:
    """Held-out prediction of the residual for every sample, FS-normalised, (n, 6) (a
    problem built with ``keep_columns``)."""
    if problem.x is None:
        raise ValueError("the columns were not kept: use stream.predict")
    cols = problem.cols(names)
    pred = np.zeros_like(problem.y)
    if len(cols) == 0:
        return pred
    for fold, coef in zip(problem.folds, fold_coefficients(problem, names)):
        for b in fold:
            sl = slice(problem.bounds[b], problem.bounds[b + 1])
            pred[sl] = problem.x[sl][:, :, cols] @ coef
    return pred


def gain(sse_before: np.ndarray, sse_after: np.ndarray) -> float:
    """Fraction of the held-out squared error removed."""
    return float(1.0 - sse_after.sum() / sse_before.sum())


#: The loud stratum of the block bootstrap: the fewest blocks holding this share of the error.
LOUD_SHARE = 0.5
#: ... but never fewer than this many: a stratum of one block is in every resample, and what
#: a term does on that one block would never be questioned (a term fitting one outlier block
#: would pass on it alone).
MIN_LOUD_BLOCKS = 2


def loudness_strata(sse: np.ndarray, share: float = LOUD_SHARE) -> np.ndarray:
    """1 for the loud blocks (the fewest, loudest first, that hold ``share`` of ``sse``; the
    one that crosses it included; at least ``MIN_LOUD_BLOCKS``), 0 for the others. How the
    error is spread over the blocks is a property of the log's excitation, not of chance: a
    resample keeps as many loud blocks as the log has."""
    order = np.argsort(sse)[::-1]
    total = float(sse.sum())
    if not total > 0:
        return np.ones(len(sse), dtype=int)
    before = (np.cumsum(sse[order]) - sse[order]) / total
    loud = max(int(np.count_nonzero(before < share - 1e-9)),   # (rounding of the cumsum)
               min(MIN_LOUD_BLOCKS, len(sse)))
    out = np.zeros(len(sse), dtype=int)
    out[order[:loud]] = 1
    return out


def bootstrap_gain(sse_before: np.ndarray, sse_after: np.ndarray, rng: np.random.Generator,
                   n_boot: int = N_BOOT, strata: np.ndarray | None = None) -> np.ndarray:
    """Gains over ``n_boot`` resamples of the blocks; with ``strata`` (a label per block)
    each stratum is resampled within itself, keeping its number of blocks."""
    n = len(sse_before)
    if strata is None:
        idx = rng.integers(0, n, size=(n_boot, n))
    else:
        idx = np.concatenate([members[rng.integers(0, len(members), (n_boot, len(members)))]
                              for members in (np.flatnonzero(strata == s)
                                              for s in np.unique(strata))], axis=1)
    return 1.0 - sse_after[idx].sum(axis=1) / sse_before[idx].sum(axis=1)


def stratified_gain(sse_before: np.ndarray, sse_after: np.ndarray,
                    rng: np.random.Generator) -> np.ndarray:
    """The diagnosis's bootstrap: loud and quiet blocks of ``sse_before`` resampled apart."""
    return bootstrap_gain(sse_before, sse_after, rng, strata=loudness_strata(sse_before))


@dataclass
class Step:
    added: str
    gain: float                 # fraction of the remaining held-out error removed
    gain_low: float             # its bootstrap lower quantile
    sse: np.ndarray             # held-out SSE per block after this step
    significant: bool


def greedy(problem: Problem, candidates, rng: np.random.Generator,
           min_gain: float = MIN_GAIN, confidence: float = CONFIDENCE,
           min_share: float = MIN_SHARE, progress=None) -> tuple[list[Step], dict]:
    """Forward selection: add the candidate with the largest held-out gain while it is
    significant. Returns the ladder (significant steps only) and, for information, the
    held-out SSE of each candidate alone."""
    base = heldout_block_sse(problem, [])
    alone = {}
    for name in candidates:
        if progress:
            progress(f"scoring {name}")
        alone[name] = heldout_block_sse(problem, [name])
    chosen: list[str] = []
    ladder: list[Step] = []
    current = base
    remaining = list(candidates)
    while remaining:
        trials = {name: (alone[name] if not chosen else
                         heldout_block_sse(problem, chosen + [name])) for name in remaining}
        best = max(trials, key=lambda n: gain(current, trials[n]))
        g = gain(current, trials[best])
        low = float(np.quantile(stratified_gain(current, trials[best], rng), 1 - confidence))
        significant = low > min_gain
        if not significant:
            break
        ladder.append(Step(best, g, low, trials[best], significant))
        chosen.append(best)
        remaining.remove(best)
        current = trials[best]
        if progress:
            progress(f"added {best}: held-out error -{100 * g:.1f} %")
    forward = [s.added for s in ladder]
    forward_steps = list(ladder)
    signature = {}
    for name in problem.sub:
        if name in candidates and (chosen or name in forward):
            signature[name] = signature_test(problem, chosen, name, rng, confidence)
    confirmed = {n for n, v in signature.items() if v["confirmed"]}
    kept = prune(problem, forward, base, min_share, progress, protected=confirmed)
    # A term its own signature confirms joins the model even when a neighbouring family had
    # absorbed it in the forward pass (lost motion fitted as friction and hysteresis).
    kept += [n for n in sorted(confirmed) if n not in kept]
    if kept != forward:
        ladder = _rebuild(problem, kept, base, rng, confidence)
    gains = {s.added: s.gain for s in forward_steps}
    return ladder, {"base": base, "alone": alone, "forward": forward, "forward_gain": gains,
                    "dropped": [n for n in forward if n not in kept], "signature": signature}


#: A signature confirms its effect when adding the effect to the model removes more than this
#: share of the held-out error on the signature's samples, at the bootstrap's lower quantile,
#: and does not raise the held-out error overall.
SIGNATURE_MIN_GAIN = 0.05


def signature_test(problem: Problem, chosen: list[str], name: str, rng: np.random.Generator,
                   confidence: float = CONFIDENCE) -> dict:
    """What ``name`` adds to the model ``chosen`` (without it) on its signature's samples (and
    over the whole log): gains and the bootstrap lower quantile."""
    without = [c for c in chosen if c != name]
    with_it = without + [name]
    sub_before = heldout_block_sse(problem, without, subset=name)
    sub_after = heldout_block_sse(problem, with_it, subset=name)
    before = heldout_block_sse(problem, without)
    after = heldout_block_sse(problem, with_it)
    samples = int(problem.sub[name][3].sum())
    if sub_before.sum() <= 0:
        return {"samples": samples, "gain": 0.0, "gain_lower": 0.0, "overall_gain": 0.0,
                "confirmed": False}
    low = float(np.quantile(stratified_gain(sub_before, sub_after, rng), 1 - confidence))
    overall = gain(before, after)
    return {"samples": samples, "gain": gain(sub_before, sub_after), "gain_lower": low,
            "overall_gain": overall,
            "confirmed": bool(low > SIGNATURE_MIN_GAIN and overall > 0.0)}


def prune(problem: Problem, chosen: list[str], base: np.ndarray, min_share: float,
          progress=None, protected=frozenset()) -> list[str]:
    """Drop, weakest first, every chosen term whose removal costs less than ``min_share`` of
    the baseline held-out squared error (never one of ``protected``)."""
    chosen = list(chosen)
    total = base.sum()
    while len(chosen) > 1:
        full = heldout_block_sse(problem, chosen).sum()
        costs = {name: (heldout_block_sse(problem, [c for c in chosen if c != name]).sum()
                        - full) / total for name in chosen if name not in protected}
        if not costs:
            break
        weakest = min(costs, key=costs.get)
        if costs[weakest] >= min_share:
            break
        chosen.remove(weakest)
        if progress:
            progress(f"dropped {weakest}: only {100 * costs[weakest]:.1f} % of the error is "
                     "its own")
    return chosen


def _rebuild(problem: Problem, names: list[str], base: np.ndarray,
             rng: np.random.Generator, confidence: float) -> list[Step]:
    steps, current, chosen = [], base, []
    for name in names:
        chosen.append(name)
        sse = heldout_block_sse(problem, chosen)
        low = float(np.quantile(stratified_gain(current, sse, rng), 1 - confidence))
        steps.append(Step(name, gain(current, sse), low, sse, True))
        current = sse
    return steps
