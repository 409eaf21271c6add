"""The whole diagnosis of one log: where the gap lies, which effects cause it, how far it
shrinks. Returns one JSON-ready dict (keys documented in ``docs/diagnosis.md``)."""
from __future__ import annotations

import time

import numpy as np

from delta6.core.design import Design
from delta6.core.model import AXES
from delta6.diagnosis import gap, physics, selection
from delta6.diagnosis.data import GapData
from delta6.diagnosis.terms import TERMS
from delta6.link.logfile import LogData


def _p99(values_pct: np.ndarray) -> list[float]:
    return np.percentile(np.abs(values_pct), 99, axis=0).tolist()


def diagnose(log: LogData, design: Design, **kwargs) -> dict:
    """Diagnose a log read with ``delta6.link.logfile.read_log`` (see :func:`diagnose_data`)."""
    return diagnose_data(GapData.from_log(log, design), **kwargs)


def diagnose_data(data: GapData, *, seed: int = 0, progress=None,
                  min_gain: float = selection.MIN_GAIN,
                  confidence: float = selection.CONFIDENCE,
                  min_share: float = selection.MIN_SHARE) -> dict:
    """The diagnosis of prepared data (the caller may reuse ``data``, e.g. for the report)."""
    started = time.perf_counter()
    design = data.design
    if progress:
        progress("model and breakdowns")
    where = gap.where(data)

    terms = [t for t in TERMS if t.available(data)]
    skipped = [t.name for t in TERMS if not t.available(data)]
    problem = selection.build_problem(data, terms, progress=progress)
    rng = np.random.default_rng(seed)
    ladder, info = selection.greedy(problem, [t.name for t in terms], rng, min_gain=min_gain,
                                    confidence=confidence, min_share=min_share,
                                    progress=progress)
    base_sse = info["base"]

    def heldout_pct(names):
        return 100.0 * (problem.y - selection.heldout_prediction(problem, names))

    candidates = []
    for term in terms:
        sse = info["alone"][term.name]
        boot = selection.bootstrap_gain(base_sse, sse, rng)
        candidates.append({
            "name": term.name,
            "heldout_p99_pct": _p99(heldout_pct([term.name])),
            "score": selection.gain(base_sse, sse),
            "score_ci": [float(np.quantile(boot, 0.005)), float(np.quantile(boot, 0.995))],
        })
    candidates.sort(key=lambda c: c["score"], reverse=True)

    steps = []
    notes: list[str] = []
    chosen: list[str] = []
    final_pct = data.residual_pct
    for step in ladder:
        chosen.append(step.added)
        final_pct = heldout_pct(chosen)
        coef = selection.fit(problem, chosen)
        params = {}
        cols = 0
        for name in chosen:
            term = problem.terms[name]
            width = len(term.param_names)
            params[name] = term.summarize(coef[cols:cols + width])
            cols += width
        notes += physics.warnings(step.added, params[step.added])
        steps.append({"added": step.added, "heldout_p99_pct": _p99(final_pct),
                      "gain": step.gain, "gain_lower": step.gain_low,
                      "params": params[step.added], "all_params": params})

    baseline_pct = data.residual_pct
    base_total = float(base_sse.sum())
    left = float(((final_pct / 100.0) ** 2).sum())
    result = {
        "baseline_heldout_p99_pct": _p99(baseline_pct),
        "present": chosen,
        "ladder": steps,
        "candidates": candidates,
        "unexplained": {
            "table_v": gap.percent_table(final_pct),
            "share_of_squared_error": left / base_total if base_total > 0 else 0.0,
            "cross_axis": gap.cross_axis_sensitivity(final_pct / 100.0 * data.fs,
                                                     data.reference, data.fs),
        },
        "where": where,
        "skipped": skipped,
        "warnings": notes,
        "axes": list(AXES),
        "full_scale": data.fs.tolist(),
        "samples": len(data),
        "settings": {"blocks": problem.n_blocks, "folds": len(problem.folds),
                     "buffer_blocks": selection.BUFFER_BLOCKS, "min_gain": min_gain,
                     "confidence": confidence, "min_share": min_share,
                     "bootstrap": selection.N_BOOT, "seed": seed},
        "design": {"name": design.name, "hash": f"0x{design.hash32():08x}"},
        "seconds": time.perf_counter() - started,
    }
    return result
