"""Where the gap lies: the analytical model's error broken down every way a user asks about.

All errors are in percent of each axis's full scale (``delta6.core.spec.full_scale``), the form of
the paper's Table V. Every function takes the :class:`~delta6.diagnosis.data.GapData` of a log
and returns plain dicts of lists (they go straight into the JSON and the report).
"""
from __future__ import annotations

import numpy as np

from delta6.core import accuracy
from delta6.core.model import AXES
from delta6.diagnosis.data import GapData

_PIECE = 100_000


def percent_table(err_pct: np.ndarray) -> dict:
    """Per-axis percentiles of |error| (already in % FS): {"p50": [6], ..., "max": [6]}."""
    out = accuracy.table(err_pct)
    out["max"] = out.pop("p100")
    return out


def table_v(data: GapData) -> dict:
    """The paper's Table V form for the whole log."""
    return percent_table(data.residual_pct)


def cross_axis_sensitivity(residual: np.ndarray, reference: np.ndarray, fs: np.ndarray) -> dict:
    """The paper's Fig. 9 metric: the FS-normalised residual regressed on the FS-normalised
    reference. ``matrix[i][j]`` is the residual of axis j per unit reference on axis i (rows:
    excited axis, columns: responding axis), fitted jointly over all six axes with an
    intercept because a random trajectory excites every axis at once. Diagonal: on-axis gain
    error; off-diagonal: cross-axis sensitivity; both ideally zero. (Normal equations summed
    piece by piece: seven columns, so long logs need no copy of the whole design.)"""
    gram = np.zeros((7, 7))
    rhs = np.zeros((7, 6))
    for a in range(0, len(reference), _PIECE):
        x = np.hstack([reference[a:a + _PIECE] / fs, np.ones((len(reference[a:a + _PIECE]), 1))])
        gram += x.T @ x
        rhs += x.T @ (residual[a:a + _PIECE] / fs)
    coef = np.linalg.lstsq(gram, rhs, rcond=None)[0]
    matrix = coef[:6]
    off = ~np.eye(6, dtype=bool)
    return {"axes": list(AXES), "matrix": matrix.tolist(),
            "mean_abs_offdiagonal": float(np.abs(matrix[off]).mean()),
            "mean_abs_diagonal": float(np.abs(np.diag(matrix)).mean())}


def _binned(err_pct: np.ndarray, labels: np.ndarray, names: list[str]) -> list[dict]:
    rows = []
    for code, name in enumerate(names):
        sel = labels == code
        n = int(sel.sum())
        if n == 0:
            rows.append({"bin": name, "n": 0, "p99": [None] * 6, "mean": [None] * 6})
            continue
        rows.append({"bin": name, "n": n,
                     "p99": np.percentile(np.abs(err_pct[sel]), 99, axis=0).tolist(),
                     "mean": err_pct[sel].mean(axis=0).tolist()})
    return rows


def _quantile_bins(values: np.ndarray, k: int, unit: str, fmt: str = "{:.3g}"):
    edges = np.quantile(values, np.linspace(0, 1, k + 1))
    labels = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, k - 1)
    names = [f"{fmt.format(edges[i])}..{fmt.format(edges[i + 1])} {unit}" for i in range(k)]
    return labels, names


def by_region(data: GapData) -> list[dict]:
    """3 x 3 regions of the TCP workspace: distance from the axis (tertiles) x height."""
    pos = data.position_mm
    radial = np.hypot(pos[:, 0], pos[:, 1])
    r_lab, r_names = _quantile_bins(radial, 3, "mm")
    z_lab, z_names = _quantile_bins(pos[:, 2], 3, "mm")
    labels = r_lab * 3 + z_lab
    names = [f"r {rn}, z {zn}" for rn in r_names for zn in z_names]
    return _binned(data.residual_pct, labels, names)


def by_direction(data: GapData) -> list[dict]:
    """Loading (the load grows), unloading (it shrinks) and holding still, judged on the
    FS-normalised norm of the model wrench; motion slower than 1 % FS/s counts as still."""
    load = np.linalg.norm(data.model / data.fs, axis=1)
    rate = np.gradient(load, data.t)
    labels = np.where(rate > 0.01, 0, np.where(rate < -0.01, 1, 2))
    return _binned(data.residual_pct, labels, ["loading", "unloading", "still"])


def by_speed(data: GapData) -> list[dict]:
    """Quintiles of joint-space speed |d theta_e / dt|."""
    labels, names = _quantile_bins(np.linalg.norm(data.velocity, axis=1), 5, "rad/s")
    return _binned(data.residual_pct, labels, names)


def over_time(data: GapData, segments: int = 10) -> dict:
    """p99 per time segment and the drift of the mean residual (% FS per hour)."""
    idx = np.array_split(np.arange(len(data.t)), segments)
    rows = []
    for i, sel in enumerate(idx):
        rows.append({"bin": f"{data.t[sel[0]]:.0f}..{data.t[sel[-1]]:.0f} s", "n": len(sel),
                     "p99": np.percentile(np.abs(data.residual_pct[sel]), 99, axis=0).tolist(),
                     "mean": data.residual_pct[sel].mean(axis=0).tolist()})
    hours = (data.t - data.t[0]) / 3600.0
    slope = np.polyfit(hours, data.residual_pct, 1)[0] if hours[-1] > 0 else np.zeros(6)
    return {"segments": rows, "drift_pct_per_hour": np.asarray(slope).tolist()}


def by_band(data: GapData) -> dict:
    """Share of the residual's variance in frequency bands (periodogram of each axis)."""
    rate = 1.0 / np.median(np.diff(data.t))
    nyq = rate / 2
    edges = [0.0, 0.05, 0.5, 2.0, 5.0, nyq]
    edges = sorted(set(e for e in edges if e <= nyq))
    spec = np.abs(np.fft.rfft(data.residual_pct - data.residual_pct.mean(axis=0), axis=0)) ** 2
    freqs = np.fft.rfftfreq(len(data.t), 1.0 / rate)
    total = spec[1:].sum(axis=0)
    total = np.where(total > 0, total, 1.0)
    bands = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (freqs > lo) & (freqs <= hi)
        bands.append({"band": f"{lo:g}..{hi:g} Hz", "share": (spec[sel].sum(axis=0) / total)
                      .tolist()})
    return {"rate_hz": rate, "bands": bands}


def by_temperature(data: GapData) -> dict | None:
    """p99 per temperature quintile and the slope of the mean residual (% FS per degC)."""
    if data.temp_c is None:
        return None
    temp = data.temp_c
    if np.ptp(temp) < 0.5:
        return {"bins": [], "slope_pct_per_degc": [0.0] * 6, "note": "temperature constant"}
    labels, names = _quantile_bins(temp, 5, "degC")
    slope = np.polyfit(temp, data.residual_pct, 1)[0]
    return {"bins": _binned(data.residual_pct, labels, names),
            "slope_pct_per_degc": np.asarray(slope).tolist()}


def where(data: GapData) -> dict:
    """Everything above, in one dict. A whole-log map that only one breakdown uses (the
    TCP's position, the joints' speed) is dropped from ``data`` once that breakdown is made:
    on a long log each is 50 to 100 MB, and the spectrum's arrays come after them."""
    out = {"table_v": table_v(data),
           "cross_axis": cross_axis_sensitivity(data.residual, data.reference, data.fs),
           "region": by_region(data)}
    data.__dict__.pop("position_mm", None)
    out["direction"] = by_direction(data)
    out["speed"] = by_speed(data)
    data.__dict__.pop("velocity", None)
    return {**out, "time": over_time(data), "band": by_band(data),
            "temperature": by_temperature(data)}
