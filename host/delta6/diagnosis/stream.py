"""A log in pieces: the columns of the candidate terms are built piece by piece, in time order,
with every history feature carried from one piece to the next, so that memory stays bounded
whatever the log's length (a 2 x 10^6-sample log never holds more than one piece's columns).

Each piece is built on its samples plus a margin on both sides (local derivatives and the
look-ahead of the backlash dwells need neighbours); the history operators (plays, lags) start
from the exact state the previous piece handed off, so the columns equal those of the whole log
built at once. Two consumers: the per-block Gram summaries (``accumulate``) and the held-out
predictions of fitted models (``predict``).
"""
from __future__ import annotations

import ctypes
import math
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from delta6.diagnosis.data import GapData

#: Samples per piece: the columns of ~270 parameters for 10,000 samples take 130 MB, and the
#: families' intermediate arrays about as much again.
PIECE_SAMPLES = 10_000
#: Margin on either side of a piece, s: longer than any backlash dwell and its look-ahead.
MARGIN_S = 10.0


def _trimmer():
    """glibc's ``malloc_trim``: hands freed heap memory back to the system. Each piece
    allocates and frees a few hundred MB of arrays; glibc raises its mmap threshold after the
    first frees and then serves such arrays from a heap that it does not shrink by itself, so
    without a trim the resident memory creeps up piece after piece. None elsewhere."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        return libc.malloc_trim
    except (OSError, AttributeError):
        return None


_TRIM = _trimmer()


def release_memory() -> None:
    if _TRIM is not None:
        _TRIM(0)


def margin_samples(data: GapData) -> int:
    return max(8, int(math.ceil(MARGIN_S / data.step)))


def pieces(data: GapData, size: int = PIECE_SAMPLES) -> Iterator[tuple[int, int, slice,
                                                                     GapData]]:
    """(start, stop, keep, view) for consecutive pieces [start, stop) of the log; ``view``
    covers the piece with its margins and continues the history of the previous view;
    ``keep`` is the piece's part of the view."""
    n = len(data)
    margin = margin_samples(data)
    size = max(size, 2 * margin + 1)
    carry: dict = {}
    for a in range(0, n, size):
        b = min(n, a + size)
        lo, hi = max(0, a - margin), min(n, b + margin)
        nxt = max(0, b - margin)
        view = data.piece(lo, hi, carry, handoff=nxt - 1 if nxt > 0 and b < n else None)
        yield a, b, slice(a - lo, b - lo), view
        carry = view.carry_out if nxt > 0 else {}
        del view
        release_memory()


def columns(view: GapData, terms, keep: slice) -> np.ndarray:
    """The FS-normalised columns of ``terms`` on the ``keep`` part of a view, (m, 6, P)."""
    p = sum(len(t.param_names) for t in terms)
    out = np.empty((keep.stop - keep.start, 6, p))
    at = 0
    for term in terms:
        width = len(term.param_names)
        out[:, :, at:at + width] = term.columns(view)[keep]
        at += width
    out /= view.fs[None, :, None]
    return out


class ColumnCache:
    """The columns of a streamed pass, kept on disk (float32) for the next pass: building them
    costs far more than reading them back. Plain file reads, not a memory map, so the cache
    never counts against the process's memory.

    ``reuse``: (an earlier pass's cache, per column of this pass the column of that cache it
    repeats, -1 for a new one). Only the new columns are written to this cache's file; the
    others are read from the earlier one (a second pass that changes one family of ~270
    columns stores that family's, not gigabytes more of scratch disk on a long log)."""

    def __init__(self, directory, width: int, reuse: tuple["ColumnCache", np.ndarray] | None
                 = None):
        self.path = Path(directory) / "columns.f32"
        self.width = width
        self.base, self.source = (None, None) if reuse is None else \
            (reuse[0], np.asarray(reuse[1], dtype=int))
        self.own = np.arange(width) if reuse is None else np.flatnonzero(self.source < 0)
        self.path.write_bytes(b"")
        self.written = 0

    def write(self, a: int, x: np.ndarray) -> None:
        assert a == self.written, "pieces are cached in order"
        if self.base is not None:
            x = x[:, :, self.own]
        with open(self.path, "ab") as f:
            f.write(np.ascontiguousarray(x, dtype=np.float32).tobytes())
        self.written += len(x)

    def read(self, a: int, b: int) -> np.ndarray:
        return self.read32(a, b).astype(float)

    def read32(self, a: int, b: int) -> np.ndarray:
        """Samples [a, b) as written, (b - a, 6, width) float32."""
        row = 6 * len(self.own)
        own = np.fromfile(self.path, dtype=np.float32, count=(b - a) * row,
                          offset=a * row * 4).reshape(b - a, 6, len(self.own))
        return self._with_base(own, lambda: self.base.read32(a, b))

    def rows(self, indices) -> np.ndarray:
        """The samples ``indices`` (a few thousand, read one by one), (m, 6, width) float32."""
        row = 6 * len(self.own)
        with open(self.path, "rb") as f:
            out = []
            for i in indices:
                f.seek(int(i) * row * 4)
                out.append(np.fromfile(f, dtype=np.float32, count=row))
        own = np.asarray(out, dtype=np.float32).reshape(len(out), 6, len(self.own))
        return self._with_base(own, lambda: self.base.rows(indices))

    def _with_base(self, own: np.ndarray, base) -> np.ndarray:
        if self.base is None:
            return own
        out = np.empty(own.shape[:2] + (self.width,), dtype=np.float32)
        out[:, :, self.own] = own
        shared = self.source >= 0
        out[:, :, shared] = base()[:, :, self.source[shared]]
        return out


def reused_columns(first_terms, second_terms) -> np.ndarray:
    """Per column of ``second_terms``, the column of ``first_terms`` that is the same (the same
    term object at either place), or -1 (a changed family's): ``ColumnCache``'s ``reuse``."""
    at, start = 0, {}
    for term in first_terms:
        start[id(term)] = at
        at += len(term.param_names)
    out = []
    for term in second_terms:
        width = len(term.param_names)
        first = start.get(id(term))
        out.extend(range(first, first + width) if first is not None else [-1] * width)
    return np.asarray(out, dtype=int)


def blocks_in(bounds: np.ndarray, a: int, b: int) -> Iterator[tuple[int, int, int]]:
    """(block, start, stop) of the blocks' parts inside [a, b)."""
    first = int(np.searchsorted(bounds, a, side="right") - 1)
    for blk in range(first, len(bounds) - 1):
        lo, hi = max(a, bounds[blk]), min(b, bounds[blk + 1])
        if lo >= hi:
            if bounds[blk] >= b:
                break
            continue
        yield blk, lo, hi


def accumulate(data: GapData, terms, bounds: np.ndarray, signatures: dict | None = None,
               keep_columns: bool = False, cache: ColumnCache | None = None,
               progress: Callable[[str], None] | None = None,
               piece_samples: int = PIECE_SAMPLES):
    """One pass over the log: per block, the Gram matrix X^T X, X^T y and y^T y of the
    FS-normalised columns of all ``terms`` against the residual; and the same over each
    signature's samples (``signatures``: name -> function of a view giving a (n,) mask).
    Returns (gram, xty, yty, sub, x) where ``sub`` maps a signature name to its (gram, xty,
    yty, count) and ``x`` is the whole column array when ``keep_columns`` (else None).
    ``piece_samples``: samples per piece; terms whose columns come from the whole log rather
    than from the view they are given need one piece as long as the log."""
    n_blocks = len(bounds) - 1
    p = sum(len(t.param_names) for t in terms)
    gram = np.zeros((n_blocks, p, p))
    xty = np.zeros((n_blocks, p))
    yty = np.zeros(n_blocks)
    signatures = signatures or {}
    sub = {name: (np.zeros((n_blocks, p, p)), np.zeros((n_blocks, p)), np.zeros(n_blocks),
                  np.zeros(n_blocks)) for name in signatures}
    x_all = np.empty((len(data), 6, p)) if keep_columns else None
    for a, b, keep, view in pieces(data, piece_samples):
        if progress:
            progress(f"columns of samples {a}..{b} of {len(data)}")
        x = columns(view, terms, keep)
        masks = {name: np.asarray(fn(view), bool)[keep] for name, fn in signatures.items()}
        if x_all is not None:
            x_all[a:b] = x
        if cache is not None:
            cache.write(a, x)
        y = data.residual[a:b] / data.fs
        for blk, lo, hi in blocks_in(bounds, a, b):
            rows = slice(lo - a, hi - a)
            xb = x[rows].reshape(-1, p)
            yb = y[rows].reshape(-1)
            gram[blk] += xb.T @ xb
            xty[blk] += xb.T @ yb
            yty[blk] += yb @ yb
            for name, mask in masks.items():
                m = mask[rows]
                if not m.any():
                    continue
                xm = x[rows][m].reshape(-1, p)
                ym = y[rows][m].reshape(-1)
                g, v, s, c = sub[name]
                g[blk] += xm.T @ xm
                v[blk] += xm.T @ ym
                s[blk] += ym @ ym
                c[blk] += m.sum()
    return gram, xty, yty, sub, x_all


class Tails:
    """Exact percentiles >= ``q`` of |values| per column, fed piece by piece: keeps only the
    largest values that ``np.percentile`` (linear interpolation) needs."""

    def __init__(self, n: int, q: float = 99.0, columns: int = 6):
        self.n = n
        self.q = q
        self.k = n - int(math.floor(q / 100.0 * (n - 1)))
        self.top = np.zeros((0, columns))
        self.seen = 0

    def add(self, values: np.ndarray) -> None:
        both = np.concatenate([self.top, np.abs(values)], axis=0)
        self.seen += len(values)
        if len(both) > self.k:
            both = np.partition(both, len(both) - self.k, axis=0)[-self.k:]
        self.top = both

    def percentile(self) -> np.ndarray:
        assert self.seen == self.n, "every sample must be added before the percentile"
        h = self.q / 100.0 * (self.n - 1)
        lo = int(math.floor(h))
        top = np.sort(self.top, axis=0)            # ascending: top[i] is rank n - k + i
        i = lo - (self.n - self.k)
        below = top[i]
        above = top[min(i + 1, len(top) - 1)]
        return below + (h - lo) * (above - below)


def predict(data: GapData, terms, bounds: np.ndarray, fold_of_block: np.ndarray,
            models: dict, store: set, x_all: np.ndarray | None = None,
            cache: ColumnCache | None = None,
            progress: Callable[[str], None] | None = None, spill=None) -> dict:
    """One pass: the held-out prediction of every model (name -> (column indices, coefficients
    per fold (K, c))), each sample predicted with the coefficients of its block's fold.
    Returns name -> p99 of the held-out error per axis (% FS) and, for the names in
    ``store``, name -> the FS-normalised prediction itself (a :class:`KeptPrediction`, float32,
    (n, 6)). ``x_all``: the whole log's columns when they were kept, ``cache`` the columns of
    an earlier pass (no columns are built then). ``spill``: a directory where the stored
    predictions wait on disk, not in memory (long logs)."""
    tails = {name: Tails(len(data)) for name in models}
    kept = {name: KeptPrediction(len(data), None if spill is None
                                 else Path(spill) / f"prediction-{i}.f32")
            for i, name in enumerate(sorted(store, key=repr))}
    stored = x_all is not None or cache is not None
    spans = ([(a, min(len(data), a + PIECE_SAMPLES), None, None)
              for a in range(0, len(data), PIECE_SAMPLES)] if stored else pieces(data))
    for a, b, keep, view in spans:
        if progress:
            progress(f"held-out predictions of samples {a}..{b} of {len(data)}")
        if x_all is not None:
            x = x_all[a:b]
        elif cache is not None:
            x = cache.read(a, b)
        else:
            x = columns(view, terms, keep)
        y = data.residual[a:b] / data.fs
        fold = fold_of_block[np.searchsorted(bounds, np.arange(a, b), side="right") - 1]
        for name, (cols, coefs) in models.items():
            if len(cols):
                pred = np.einsum("nap,np->na", x[:, :, cols], coefs[fold])
            else:
                pred = np.zeros_like(y)
            tails[name].add(100.0 * (y - pred))
            if name in kept:
                kept[name].write(a, pred)
        del x
    return {"p99": {name: t.percentile() for name, t in tails.items()}, "pred": kept}


class KeptPrediction:
    """A held-out prediction (n, 6) kept in float32, written piece by piece in time order: in
    memory, or in a scratch file at ``path`` (a long log's ladder steps are used one at a
    time: only the one in use is in memory)."""

    def __init__(self, n: int, path: Path | None = None):
        self.n = n
        self.path = path
        self.array = np.empty((n, 6), dtype=np.float32) if path is None else None
        self.written = 0
        if path is not None:
            path.write_bytes(b"")

    def write(self, a: int, pred: np.ndarray) -> None:
        assert a == self.written, "pieces are kept in order"
        if self.array is not None:
            self.array[a:a + len(pred)] = pred
        else:
            with open(self.path, "ab") as f:
                f.write(np.ascontiguousarray(pred, dtype=np.float32).tobytes())
        self.written += len(pred)

    def read(self) -> np.ndarray:
        """The whole prediction; a scratch file is removed once read."""
        assert self.written == self.n, "every piece must be written first"
        if self.array is not None:
            return self.array
        out = np.fromfile(self.path, dtype=np.float32).reshape(self.n, 6)
        self.path.unlink()
        return out
