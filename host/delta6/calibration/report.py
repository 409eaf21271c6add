"""The calibration report: Markdown with two plots (headless matplotlib)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from delta6.calibration.fit import effects_to_fit
from delta6.core.calibrated import CalibratedModel
from delta6.core.calibration import SECTIONS
from delta6.core.model import AXES, wrench
from delta6.core.outputs import written_together
from delta6.core.spec import full_scale
from delta6.diagnosis.report import pyplot

#: The report's files; the Markdown names the plots.
MARKDOWN, HELDOUT_PLOT, RESIDUAL_PLOT = "calibration.md", "heldout_p99.png", "residual.png"


def _row(label: str, values) -> str:
    return f"| {label} | " + " | ".join(f"{v:.2f}" for v in values) + " |"


def corrected(fit) -> str:
    """The corrected effects: those the diagnosis named (or --effect gave), apart from those
    the calibration added because they lowered the held-out error further."""
    effects = list(fit.calibration.effects)
    if not effects:
        return ("nothing (no significant unmodelled effect)" if fit.diagnosis is not None
                else "nothing (the effects named fitted to nothing here)")
    if fit.diagnosis is None:
        return ", ".join(effects) + f" (chosen by {fit.chosen_by})"
    named = set(effects_to_fit(fit.diagnosis))
    parts = []
    if named & set(effects):
        parts.append(", ".join(e for e in effects if e in named) + " (the diagnosis's verdict)")
    added = [e for e in effects if e not in named]
    if added:
        parts.append(", ".join(added) + " (added: each lowered the held-out error further)")
    return "; ".join(parts)


def write_report(fit, log, design, out_dir, source: str = "") -> Path:
    """Write ``calibration.md`` and its plots into ``out_dir``; returns the report's path.
    The files are written under temporary names and renamed together, the Markdown last (an
    earlier one removed first): a folder with calibration.md holds its whole report, and an
    interrupted run leaves no half-written file."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / MARKDOWN
    with written_together(out / HELDOUT_PLOT, out / RESIDUAL_PLOT, path) as temps:
        _write_files(fit, log, design, source, *temps)
    return path


def _write_files(fit, log, design, source: str, heldout_png: Path, residual_png: Path,
                 markdown: Path) -> None:
    plt = pyplot()
    cal = fit.calibration
    fs = full_scale(design)
    before = 100.0 * (wrench(design, log.theta) - log.wrench) / fs
    after = 100.0 * (CalibratedModel(design, cal).predict(log) - log.wrench) / fs

    fig, ax = plt.subplots(figsize=(7, 3.2))
    x = np.arange(6)
    ax.bar(x - 0.2, fit.heldout_before["p99_pct"], 0.4, label="analytical")
    ax.bar(x + 0.2, fit.heldout_after["p99_pct"], 0.4, label="calibrated")
    ax.set_xticks(x, AXES)
    ax.set_ylabel("held-out p99 |error|, % FS")
    ax.legend()
    try:
        fig.savefig(heldout_png, dpi=110, bbox_inches="tight", format="png")
    finally:
        plt.close(fig)

    fig, axes = plt.subplots(6, 1, figsize=(8, 9), sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(log.t, before[:, i], lw=0.4, label="analytical")
        ax.plot(log.t, after[:, i], lw=0.4, label="calibrated")
        ax.set_ylabel(f"{AXES[i]} % FS")
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("t, s (the held-out blocks are the last fifth)")
    try:
        fig.savefig(residual_png, dpi=90, bbox_inches="tight", format="png")
    finally:
        plt.close(fig)

    lines = [f"# Delta6 calibration '{cal.name}'{': ' + source if source else ''}", "",
             f"Design `{cal.design_name}` (0x{cal.design_hash:08x}); calibration hash "
             f"0x{cal.hash32():08x}; {len(log)} samples; fitted in {fit.seconds:.1f} s.", "",
             f"Corrects: {corrected(fit)}.", ""]
    how = "as stated" if fit.latency_given else "fitted"
    lines += [f"The reference sensor is late by {1e3 * fit.latency_s:.1f} ms ({how}): a "
              "property of the rig, not applied on the board.", ""]
    lines += [f"- {n}" for n in fit.notes]
    lines += ["", "## Held-out Table V (% FS)", "", "| | " + " | ".join(AXES) + " |",
              "|---|" + "---|" * 6]
    tables = [("analytical", fit.heldout_before), ("calibrated", fit.heldout_after)]
    if fit.latency_s > 0 and fit.heldout_after_rig is not None:
        late = f"{1e3 * fit.latency_s:.1f} ms later reference"
        tables += [(f"analytical, {late}", fit.heldout_before_rig),
                   (f"calibrated, {late}", fit.heldout_after_rig)]
    for label, table in tables:
        for key in ("p95_pct", "p99_pct", "max_pct"):
            lines.append(_row(f"{label} {key[:-4]}", table[key]))
    lines += ["", f"![held-out p99]({HELDOUT_PLOT})", "", "## Parameters", ""]
    for section, pairs in SECTIONS.items():
        lines.append(f"- **{section}**: " + "; ".join(
            f"{key} = {np.round(np.asarray(getattr(cal, attr), dtype=float), 6).tolist()}"
            for key, attr in pairs))
    lines += ["", "## Residual over the log (fit and held-out blocks)", "",
              f"![residual]({RESIDUAL_PLOT})", ""]
    markdown.write_text("\n".join(lines), encoding="utf-8")
