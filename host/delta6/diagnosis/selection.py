"""Which effects are present: time-blocked held-out scoring, a block bootstrap, and greedy
forward selection.

The log is cut into contiguous time blocks; folds are contiguous runs of blocks. A term set is
fitted on the blocks outside a fold (minus one buffer block on each side, so history features
cannot leak across the boundary) and scored on the fold. Every term is linear in its
parameters, so each block is summarised once by its Gram matrix X^T X, X^T y and y^T y over the
columns of *all* candidate terms: any fit and any held-out error is then a small dense solve.

An effect is called present when two things hold:

1. forward: adding it lowers the held-out squared error by more than ``min_gain`` of what is
   left, at the ``1 - confidence`` lower quantile of a bootstrap over held-out blocks (blocks,
   not samples, are resampled because neighbouring samples are correlated). Fitting noise
   alone gives gains near zero or negative: a term fitted to data it cannot explain only adds
   variance on held-out blocks;
2. backward: taking it out of the final model raises the held-out squared error by at least
   ``min_share`` of the analytical model's. A family never matches a real effect exactly, and
   a neighbouring family can soak up a little of what the true one misses; this test keeps
   such passengers out of the verdict while keeping a genuine second effect, which carries
   its own share of the error.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from delta6.diagnosis.data import GapData
from delta6.diagnosis.terms import Term

N_BLOCKS = 40
N_FOLDS = 5
BUFFER_BLOCKS = 1
MIN_GAIN = 0.02
MIN_SHARE = 0.01
CONFIDENCE = 0.99
N_BOOT = 2000
RIDGE = 1e-9


@dataclass
class Problem:
    """Everything the selection needs, FS-normalised (each axis divided by its full scale)."""

    y: np.ndarray                 # (n, 6) residual / FS
    x: np.ndarray                 # (n, 6, P) term columns / FS
    slices: dict                  # term name -> slice of P
    terms: dict                   # term name -> Term
    bounds: np.ndarray            # (B + 1,) sample index of block edges
    gram: np.ndarray              # (B, P, P)
    xty: np.ndarray               # (B, P)
    yty: np.ndarray               # (B,)
    folds: list = field(default_factory=list)   # list of arrays of block indices

    @property
    def n_blocks(self) -> int:
        return len(self.yty)

    def cols(self, names) -> np.ndarray:
        return np.concatenate([np.arange(self.x.shape[2])[self.slices[n]] for n in names]) \
            if names else np.zeros(0, dtype=int)


def build_problem(data: GapData, terms: list[Term], n_blocks: int = N_BLOCKS,
                  n_folds: int = N_FOLDS, progress=None) -> Problem:
    y = data.residual / data.fs
    parts, slices, start = [], {}, 0
    for term in terms:
        if progress:
            progress(f"building {term.name} columns")
        cols = term.columns(data) / data.fs[None, :, None]
        parts.append(cols)
        slices[term.name] = slice(start, start + cols.shape[2])
        start += cols.shape[2]
    x = np.concatenate(parts, axis=2) if parts else np.zeros((len(y), 6, 0))
    bounds = np.linspace(0, len(y), n_blocks + 1).astype(int)
    p = x.shape[2]
    gram = np.empty((n_blocks, p, p))
    xty = np.empty((n_blocks, p))
    yty = np.empty(n_blocks)
    for b in range(n_blocks):
        sl = slice(bounds[b], bounds[b + 1])
        xb = x[sl].reshape(-1, p)
        yb = y[sl].reshape(-1)
        gram[b] = xb.T @ xb
        xty[b] = xb.T @ yb
        yty[b] = yb @ yb
    folds = np.array_split(np.arange(n_blocks), n_folds)
    return Problem(y=y, x=x, slices=slices, terms={t.name: t for t in terms}, bounds=bounds,
                   gram=gram, xty=xty, yty=yty, folds=folds)


def solve(gram: np.ndarray, xty: np.ndarray) -> np.ndarray:
    """Least squares from normal equations, scaled for conditioning, with a tiny ridge that only
    matters for exactly collinear columns (geometry parameters some poses cannot separate)."""
    if len(xty) == 0:
        return np.zeros(0)
    scale = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    g = gram / np.outer(scale, scale)
    g[np.diag_indices_from(g)] += RIDGE * max(1.0, np.trace(g) / len(g))
    return np.linalg.solve(g, xty / scale) / scale


def train_blocks(problem: Problem, fold: np.ndarray) -> np.ndarray:
    lo, hi = fold.min() - BUFFER_BLOCKS, fold.max() + BUFFER_BLOCKS
    blocks = np.arange(problem.n_blocks)
    return blocks[(blocks < lo) | (blocks > hi)]


def fit(problem: Problem, names, blocks=None) -> np.ndarray:
    cols = problem.cols(names)
    blocks = np.arange(problem.n_blocks) if blocks is None else blocks
    g = problem.gram[np.ix_(blocks, cols, cols)].sum(axis=0) if len(cols) else np.zeros((0, 0))
    v = problem.xty[np.ix_(blocks, cols)].sum(axis=0) if len(cols) else np.zeros(0)
    return solve(g, v)


def heldout_block_sse(problem: Problem, names) -> np.ndarray:
    """Held-out squared error of every block, (B,), each block predicted by the fit on the
    blocks outside its fold."""
    cols = problem.cols(names)
    sse = problem.yty.copy()
    if len(cols) == 0:
        return sse
    for fold in problem.folds:
        coef = fit(problem, names, train_blocks(problem, fold))
        for b in fold:
            g = problem.gram[b][np.ix_(cols, cols)]
            sse[b] = problem.yty[b] - 2 * coef @ problem.xty[b, cols] + coef @ g @ coef
    return sse


def heldout_prediction(problem: Problem, names) -> np.ndarray:
    """Held-out prediction of the residual for every sample, FS-normalised, (n, 6)."""
    cols = problem.cols(names)
    pred = np.zeros_like(problem.y)
    if len(cols) == 0:
        return pred
    for fold in problem.folds:
        coef = fit(problem, names, train_blocks(problem, fold))
        sl = slice(problem.bounds[fold.min()], problem.bounds[fold.max() + 1])
        pred[sl] = problem.x[sl][:, :, cols] @ coef
    return pred


def gain(sse_before: np.ndarray, sse_after: np.ndarray) -> float:
    """Fraction of the held-out squared error removed."""
    return float(1.0 - sse_after.sum() / sse_before.sum())


def bootstrap_gain(sse_before: np.ndarray, sse_after: np.ndarray, rng: np.random.Generator,
                   n_boot: int = N_BOOT) -> np.ndarray:
    idx = rng.integers(0, len(sse_before), size=(n_boot, len(sse_before)))
    return 1.0 - sse_after[idx].sum(axis=1) / sse_before[idx].sum(axis=1)


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
        low = float(np.quantile(bootstrap_gain(current, trials[best], rng), 1 - confidence))
        significant = low > min_gain
        if not significant:
            break
        ladder.append(Step(best, g, low, trials[best], significant))
        chosen.append(best)
        remaining.remove(best)
        current = trials[best]
        if progress:
            progress(f"added {best}: held-out error -{100 * g:.1f} %")
    kept = prune(problem, [s.added for s in ladder], base, min_share, progress)
    if kept != [s.added for s in ladder]:
        ladder = _rebuild(problem, kept, base, rng, confidence)
    return ladder, {"base": base, "alone": alone}


def prune(problem: Problem, chosen: list[str], base: np.ndarray, min_share: float,
          progress=None) -> list[str]:
    """Drop, weakest first, every chosen term whose removal costs less than ``min_share`` of
    the baseline held-out squared error."""
    chosen = list(chosen)
    total = base.sum()
    while len(chosen) > 1:
        full = heldout_block_sse(problem, chosen).sum()
        costs = {name: (heldout_block_sse(problem, [c for c in chosen if c != name]).sum()
                        - full) / total for name in chosen}
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
        low = float(np.quantile(bootstrap_gain(current, sse, rng), 1 - confidence))
        steps.append(Step(name, gain(current, sse), low, sse, True))
        current = sse
    return steps
