"""Per-axis error as percent of full scale, the paper's Table V form.

Every "% FS" divides by ``spec.full_scale(design)``: the larger magnitude of each axis's
converged range.
"""
from __future__ import annotations

import numpy as np

from delta6.core.model import AXES

PERCENTILES = (50, 95, 99, 100)


def error_pct_fs(estimate: np.ndarray, reference: np.ndarray, full_scale) -> np.ndarray:
    """|estimate - reference| / full scale * 100, per sample and axis, (N, 6)."""
    return 100.0 * np.abs(np.asarray(estimate) - np.asarray(reference)) / np.asarray(full_scale)


def table(err_pct: np.ndarray, which=PERCENTILES) -> dict[str, list[float]]:
    """Per-axis percentiles of |error| already in % FS: {"p50": [Fx..Mz], ...}
    ("p100" is the maximum)."""
    values = np.percentile(np.abs(np.asarray(err_pct)), which, axis=0)
    return {f"p{q:g}": [float(v) for v in row] for q, row in zip(which, values)}


def percentiles(estimate: np.ndarray, reference: np.ndarray, full_scale,
                which=PERCENTILES) -> dict[str, list[float]]:
    """{"p50": [Fx..Mz], "p95": [...], ...} in % FS ("p100" is the maximum)."""
    return table(error_pct_fs(estimate, reference, full_scale), which)


def advanced(t: np.ndarray, values: np.ndarray, latency_s: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """What a sensor that is ``latency_s`` late read for each sample: ``values`` at
    ``t + latency_s`` (linear interpolation between the rows), and the mask of the samples
    that have it (those within ``latency_s`` of the end do not). Returns (values at the
    masked samples, mask)."""
    t = np.asarray(t, dtype=float)
    values = np.asarray(values, dtype=float)
    keep = t + latency_s <= t[-1] + 1e-9 * max(1.0, abs(t[-1]))     # (rounding of t)
    if latency_s == 0:
        return values, keep
    return np.stack([np.interp(t[keep] + latency_s, t, values[:, i])
                     for i in range(values.shape[1])], axis=1), keep


def format_table(table: dict[str, list[float]], title: str = "") -> str:
    """The percentiles as a small text table, one row per percentile."""
    lines = [f"{title:<12}" + "".join(f"{a:>8}" for a in AXES)] if title is not None else []
    for key, row in table.items():
        lines.append(f"{key + ' % FS':<12}" + "".join(f"{v:8.2f}" for v in row))
    return "\n".join(lines)
