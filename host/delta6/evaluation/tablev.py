"""The paper's Table V across estimators: p95, p99 and max of |error| per axis, % FS.

An **estimator** is any object with

* ``name``: a short string, the row's label (``"analytical"``, ``"calibrated"``, ...);
* ``predict(log) -> np.ndarray``: the wrench it estimates for every sample of ``log`` (a
  ``delta6.link.logfile.LogData``: ``t``, ``theta`` (n, 6) encoder angles in rad, ...), shape
  (n, 6), Fx Fy Fz in N and Mx My Mz in N*m, in frame {E}. It sees the encoder angles and
  times only: the reference wrench ``log.wrench`` is what it is scored against.

:func:`table` scores a list of estimators on one log and returns the JSON of
``delta6 evaluate``; :func:`format_table` prints it. To add a row (a learned model, another
calibration), write a class with those two members and pass an instance along::

    class MyModel:
        name = "my-model"
        def predict(self, log):
            return ...            # (len(log), 6)

    result = tablev.table([Analytical(design), MyModel()], log, design)
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from delta6.core import accuracy, model
from delta6.core.design import Design
from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.core.spec import full_scale

#: Percentiles of Table V, and their JSON keys.
COLUMNS = ((95, "p95_pct"), (99, "p99_pct"), (100, "max_pct"))


class Estimator(Protocol):
    name: str

    def predict(self, log) -> np.ndarray: ...


class Analytical:
    """The paper's analytical model on the logged angles."""

    name = "analytical"

    def __init__(self, design: Design):
        self.design = design

    def predict(self, log) -> np.ndarray:
        return model.wrench(self.design, log.theta)


def advanced_reference(log, latency_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The reference wrench advanced by a rig's latency: what the reference sensor read
    ``latency_s`` after each sample (linear interpolation between the log's rows), and the
    samples that have it (those within ``latency_s`` of the log's end do not)."""
    return accuracy.advanced(log.t, log.wrench, latency_s)


def row(estimator: Estimator, log, fs: np.ndarray, reference: np.ndarray | None = None,
        keep: np.ndarray | None = None) -> dict:
    """One estimator's Table V row on ``log``: against ``reference`` on the samples ``keep``
    (default: the logged reference, every sample)."""
    estimate = np.asarray(estimator.predict(log), dtype=float)
    if estimate.shape != (len(log), 6):
        raise UserError(f"estimator {estimator.name!r} returned shape {estimate.shape}, "
                        f"expected ({len(log)}, 6)")
    if not np.all(np.isfinite(estimate)):
        bad = int((~np.isfinite(estimate)).any(axis=1).sum())
        raise UserError(f"estimator {estimator.name!r} gave no finite wrench for {bad} samples")
    if keep is not None:
        estimate = estimate[keep]
    t = accuracy.percentiles(estimate, log.wrench if reference is None else reference, fs,
                             [q for q, _ in COLUMNS])
    return {"estimator": estimator.name,
            **{key: t[f"p{q:g}"] for q, key in COLUMNS}}


def table(estimators, log, design: Design, rig_latency_s: float = 0.0) -> dict:
    """``{"rows": [{"estimator", "p95_pct", "p99_pct", "max_pct"}, ...], "samples": n,
    "full_scale": [6], "axes": [...], "rig_latency_s": s}`` for the estimators on one log.
    With ``rig_latency_s`` every row is scored against the reference advanced by the rig's
    latency (:func:`advanced_reference`; the last samples, which it leaves without one, are
    not scored)."""
    names = [e.name for e in estimators]
    if len(set(names)) != len(names):
        raise UserError("two estimators share a name: " + ", ".join(names))
    fs = full_scale(design)
    reference, keep = advanced_reference(log, rig_latency_s)
    if not keep.any():
        raise UserError(f"a rig latency of {rig_latency_s:g} s leaves no sample of the log "
                        "with a reference")
    return {"rows": [row(e, log, fs, reference, keep) for e in estimators],
            "samples": int(keep.sum()), "full_scale": fs.tolist(), "axes": list(AXES),
            "design": {"name": design.name, "hash": f"0x{design.hash32():08x}"},
            "rig_latency_s": float(rig_latency_s)}


def format_table(result: dict) -> str:
    """Table V as text: one line per estimator and percentile."""
    width = max([10] + [len(r["estimator"]) for r in result["rows"]])
    against = (f" (reference advanced by the rig latency, {1e3 * result['rig_latency_s']:.1f} ms)"
               if result.get("rig_latency_s") else "")
    # Columns widen for a value of a thousand per cent or more (a broken estimator), so that
    # numbers never run into each other.
    cell = max([8] + [len(f"{v:.2f}") + 2 for r in result["rows"] for _, key in COLUMNS
                      for v in r[key]])
    lines = [f"Table V: |error| in % of full scale, {result['samples']} samples{against}",
             f"{'estimator':<{width}}  {'':<4}" + "".join(f"{a:>{cell}}" for a in AXES)]
    for r in result["rows"]:
        for q, key in COLUMNS:
            label = "max" if q == 100 else f"p{q}"
            lines.append(f"{r['estimator']:<{width}}  {label:<4}"
                         + "".join(f"{v:{cell}.2f}" for v in r[key]))
    return "\n".join(lines)
