"""The human-readable diagnosis report: Markdown with plots (matplotlib, headless)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from delta6.core.calibration import NOT_APPLIED
from delta6.core.model import AXES
from delta6.diagnosis.data import GapData
from delta6.diagnosis.onchip import CAUSAL_FORMS
from delta6.diagnosis.run import SMALL_SHARE


def pyplot():
    try:
        import matplotlib
    except ImportError:  # pragma: no cover - depends on the install
        from delta6.core.errors import UserError
        raise UserError("--report needs matplotlib: pip install 'delta6[plots]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _row(label: str, values, fmt: str = "{:.2f}") -> str:
    return f"| {label} | " + " | ".join(fmt.format(v) for v in values) + " |"


def _table(header: list[str], rows: list[str]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header), *rows]


def write_report(result: dict, data: GapData, out_dir: str | Path, source: str = "") -> Path:
    """Write ``report.md`` and its PNG plots into ``out_dir``; returns the report's path."""
    plt = pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figures = {
        "ladder": _plot_ladder(plt, result),
        "cross_axis": _plot_cross_axis(plt, result),
        "direction_loops": _plot_loops(plt, data),
        "breakdown": _plot_breakdown(plt, result),
        "candidates": _plot_candidates(plt, result),
    }
    for name, fig in figures.items():
        fig.savefig(out / f"{name}.png", dpi=110, bbox_inches="tight")
        plt.close(fig)

    tv = result["where"]["table_v"]
    after = result["unexplained"]["table_v"]
    lines = [f"# Delta6 gap diagnosis{': ' + source if source else ''}", "",
             f"Design `{result['design']['name']}` ({result['design']['hash']}), "
             f"{result['samples']} samples; errors in % of each axis's full scale "
             f"({', '.join(f'{a} {v:.4g}' for a, v in zip(AXES, result['full_scale']))}).", "",
             "## Verdict", ""]
    if result["present"]:
        lines.append("Present, strongest first: " + ", ".join(f"**{p}**" for p in
                                                              result["present"]) + ".")
    elif not result["groups"]:
        lines.append("**No significant unmodelled effect**: no candidate lowers the held-out "
                     "error beyond what fitting noise gives.")
    lines += verdict_lines(result)
    lines += ["", "## Where the gap lies (Table V form, % FS)", ""]
    rows = [_row(f"analytical p{q}", tv[f"p{q}"]) for q in (50, 95, 99)]
    rows.append(_row("analytical max", tv["max"]))
    rows += [_row(f"compensated p{q} (held-out)", after[f"p{q}"]) for q in (50, 95, 99)]
    rows.append(_row("compensated max (held-out)", after["max"]))
    lines += _table(["", *AXES], rows)
    ca = result["where"]["cross_axis"]
    lines += ["", f"Cross-axis residual sensitivity (Fig. 9 metric): mean |off-diagonal| "
              f"{ca['mean_abs_offdiagonal']:.4f} FS/FS before, "
              f"{result['unexplained']['cross_axis']['mean_abs_offdiagonal']:.4f} after; "
              f"mean |diagonal| {ca['mean_abs_diagonal']:.4f} before, "
              f"{result['unexplained']['cross_axis']['mean_abs_diagonal']:.4f} after.", "",
              "![cross-axis](cross_axis.png)", "",
              "![breakdown](breakdown.png)", ""]
    for key, title in (("direction", "By direction of motion"), ("speed", "By joint speed"),
                       ("region", "By workspace region")):
        lines += [f"### {title} (p99, % FS)", ""]
        lines += _table(["bin", "n", *AXES], [
            f"| {r['bin']} | {r['n']} | " + " | ".join("-" if v is None else f"{v:.2f}"
                                                       for v in r["p99"]) + " |"
            for r in result["where"][key]])
        lines.append("")
    band = result["where"]["band"]
    lines += ["### By frequency band (share of residual variance)", ""]
    lines += _table(["band", *AXES], [_row(b["band"], b["share"], "{:.0%}")
                                      for b in band["bands"]])
    drift = result["where"]["time"]["drift_pct_per_hour"]
    lines += ["", "Drift of the mean residual: " + ", ".join(
        f"{a} {v:+.3f}" for a, v in zip(AXES, drift)) + " % FS per hour."]
    temp = result["where"]["temperature"]
    if temp:
        lines += ["Against temperature: " + ", ".join(
            f"{a} {v:+.3f}" for a, v in zip(AXES, temp["slope_pct_per_degc"])) + " % FS/degC."]
    lines += ["", "![direction loops](direction_loops.png)", "",
              "Each panel: the residual expressed as the extra torque on one joint that would "
              "explain it, against that joint's angle, coloured by the direction the joint was "
              "last moving. Separate up/down bands mean a history effect (hysteresis, "
              "friction, backlash); one band means none.", "",
              "## Which effect causes it", "",
              "Each candidate alone, fitted on training blocks and scored on held-out blocks "
              "(score: fraction of the held-out squared error it removes; 99 % bootstrap "
              "interval over blocks).", ""]
    lines += _table(["candidate", "score", "99 % interval", *(f"p99 {a}" for a in AXES)], [
        f"| {c['name']} | {c['score']:.3f} | {c['score_ci'][0]:.3f}..{c['score_ci'][1]:.3f} | "
        + " | ".join(f"{v:.2f}" for v in c["heldout_p99_pct"]) + " |"
        for c in result["candidates"]])
    if result["skipped"]:
        lines += ["", "Not testable on this log: " + ", ".join(result["skipped"])
                  + " (needs a temp_c column that varies)."]
    lines += ["", "![candidates](candidates.png)", "", "## How far it shrinks", ""]
    lines += _table(["step", "added", "gain", *(f"p99 {a}" for a in AXES)],
                    ["| 0 | analytical model | - | " + " | ".join(
                        f"{v:.2f}" for v in result["baseline_heldout_p99_pct"]) + " |"] + [
        f"| {i + 1} | {s['added']} | {s['gain']:.3f} | " + " | ".join(
            f"{v:.2f}" for v in s["heldout_p99_pct"]) + " |"
        for i, s in enumerate(result["ladder"])]
        + _without_play_row(result))
    lines += _on_chip_lines(result)
    lines += ["", "![ladder](ladder.png)", "", "### Fitted parameters (all data)", ""]
    for step in result["ladder"]:
        lines.append(f"- **{step['added']}**: " + _format_params(step["params"]))
    lines += ["", f"Left unexplained: {result['unexplained']['share_of_squared_error']:.1%} of "
              "the analytical model's held-out squared error.", ""]
    lines += _leftover_section(result)
    lines += _excitation_section(result)
    lines += ["",
              f"Settings: {result['settings']}. Run time {result['seconds']:.1f} s.", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path


def verdict_lines(result: dict) -> list[str]:
    """The verdicts beyond "present", as Markdown lines (also used by the command's summary)."""
    lines = []
    for g in result["groups"]:
        lines.append(f"- Group verdict: **{g['text']}** (the log cannot tell them apart)."
                     + (f" Named only in the group, each with under {100 * SMALL_SHARE:g} % of "
                        f"the gap of its own "
                        f"beside {', '.join(g['named_alone'])}: {', '.join(g['folded'])}."
                        if g.get("folded") else "")
                     + (" Backlash is in it as a play fitted beside the hysteresis: "
                        + ", ".join(f"{1e3 * g['play_beside']['play_rad'][j - 1]:.1f} mrad on "
                                    f"joint {j}" for j in g["play_beside"]["joints"])
                        + "; the loop takes up its switch, so the held-out error gains little"
                        " from it and the ladder leaves it out."
                        if g.get("play_beside") else ""))
    named = set(result.get("present", [])) | {m for g in result["groups"] for m in g["members"]}
    for name in sorted(named & set(NOT_APPLIED)):
        # The shrink the ladder predicts includes it: say what a calibration leaves of it.
        lines.append(f"- {name} is not corrected by `delta6 calibrate`: {NOT_APPLIED[name]} "
                     "(the ladder's shrink counts it; the calibration's held-out table "
                     "does not).")
    lines += _beyond_encoders_lines(result)
    for p in result["partial"]:
        if p.get("fragment"):
            lines.append(f"- Not named: {p['name']} explains less of the gap, alone and in "
                         "the model, than the structured leftover "
                         f"({100 * p['leftover_share']:.0f} %): it may be a fragment of it (a "
                         "neighbour's misfit, or part of an effect the vocabulary lacks).")
            continue
        lines.append(f"- Not named: {p['name']} carries only {100 * p['share_of_gap']:.0f} % "
                     "of the gap while a structured leftover remains: it may be absorbing part "
                     "of an effect the vocabulary lacks.")
    for p in result.get("stand_ins", []):
        lines.append(f"- Not named: {p['name']} carries {100 * p['share_of_gap']:.0f} % of the "
                     f"gap, and {' or '.join(p['stand_ins'])} fits as well in its place beside "
                     "a structured leftover: the log cannot tell which, if either, is there.")
    for m in result.get("minor", []):
        share = m.get("share_with_traded", m["share_of_gap"])
        alone = m.get("share_alone")
        also = "" if alone is None else f" and removes {100 * alone:.1f} % alone"
        why = ("its own signature shows it, but it is too small to name" if m.get("confirmed")
               else "in the ladder, but too little to tell it from its neighbours")
        lines.append(f"- Not named: {m['name']} carries only {100 * share:.1f} % "
                     f"of the gap (with the families it trades with){also}: {why}.")
    for sp in result.get("straight_part", []):
        lines.append(f"- Not named: {sp['name']} is the straight-line part of "
                     f"{sp['straight_part_of']} (a stiffening with the nominal rate at rest "
                     "leaves the same error, within the noise): the log shows no part of its "
                     "own.")
    for f in result.get("below_noise", []):
        lines.append(f"- Not named: {f['name']} removes only "
                     f"{100 * f['share_of_noise_floor']:.0f} % of the noise floor's squared "
                     "error (less than one axis's white noise): it cannot be told from noise.")
    for name, check in result["implausible"].items():
        worst = max(check["checks"], key=lambda c: c["ratio"])
        lines.append(f"- Not named: {name} fits only by going out of bounds ({worst['quantity']}"
                     f" {worst['largest']:.3g}, plausible up to {worst['limit']:.3g}).")
    # The harness's clamp and cable describe a named harness only: a second pass can stand
    # and its family still end partial, minor or below the noise.
    harness_named = "harness" in result.get("present", []) or any(
        "harness" in g["members"] for g in result["groups"])
    clamp = result.get("harness_clamp_mm") if harness_named else None
    if clamp is not None:
        lines.append("- The harness is clamped off the plate's centre, at "
                     + ", ".join(f"{v:+.1f}" for v in clamp) + " mm (x, y, z in the plate's "
                     "frame; only the part across its pull is determined): its hinge was fitted "
                     "in the clamp's own displacement.")
    cable = result.get("harness_cable") if harness_named else None
    if cable is not None:
        lines.append("- The harness's one-sided part is one cable: stretched along "
                     + ", ".join(f"{v:+.2f}" for v in cable["direction"]) + " (x, y, z in "
                     f"the base frame), taut beyond a slack of {cable['slack_mm']:g} mm.")
    for name, test in result["signature_tests"].items():
        if test["confirmed"]:
            lines.append(f"- {name} confirmed by its own signature: on the {test['samples']} "
                         "samples where an encoder stands still across a reversal it removes "
                         f"{100 * test['gain']:.0f} % of the held-out error.")
    left = result["unexplained"]["verdict"]
    if left["structured"]:
        where = (f"joint(s) {', '.join(str(j) for j in left['joints'])}" if left["joints"]
                 else "no single joint")
        in_angle = [r["joint"] for r in left["per_joint"] if r.get("angle_structured")]
        how = (f"; a function of the own angle of joint(s) {', '.join(map(str, in_angle))} "
               "by the held-out test") if in_angle else ""
        lines.append(f"- What is left is **structured** (up to {max(left['excess_over_noise']):.1f}"
                     f" times the noise floor's variance{how}), on {where}, shape: "
                     f"**{left['shape'] or 'unresolved'}**.")
    else:
        lines.append("- What is left is at the noise floor (white).")
    unsupported = result["excitation"]["unsupported"]
    if unsupported:
        lines.append("- The log does not excite " + ", ".join(unsupported) +
                     " enough to judge them.")
    return lines


def _without_play_row(result: dict) -> list[str]:
    play = (result.get("beyond_encoders") or {}).get("backlash")
    if play is None:
        return []
    return ["| - | without the backlash's play (hardware, beyond any model on the encoders) | - | "
            + " | ".join(f"{v:.2f}" for v in play["heldout_p99_pct"]) + " |"]


def _beyond_encoders_lines(result: dict) -> list[str]:
    play = (result.get("beyond_encoders") or {}).get("backlash")
    if play is None:
        return []
    travel = max(play["travel_rms_share_of_play"])
    return ["- The backlash's play: the ladder's model on the encoders reaches a held-out p99 "
            "of " + " ".join(f"{a} {v:.2f}" for a, v in zip(AXES, play["ladder_heldout_p99_pct"]))
            + " % FS. While an encoder stands still its link turns inside the play where no "
            f"model on the encoders can follow it (RMS up to {100 * travel:.0f} % of the play, "
            "seen in the reference wrench); taking the play away (a tighter magnet holder) would "
            "reach " + " ".join(f"{a} {v:.2f}" for a, v in zip(AXES, play["heldout_p99_pct"]))
            + " % FS."]


def _on_chip_lines(result: dict) -> list[str]:
    on_chip = result.get("on_chip") or {}
    if on_chip.get("heldout_p99_pct") is None:
        return []
    if not on_chip["families"]:
        return ["", "On the chip: nothing in the ladder is applied on a board ("
                + ", ".join(on_chip["not_applied"]) + "): a calibration leaves the analytical "
                "model's error."]
    lines = ["", "On the chip (a forecast of what `delta6 calibrate` leaves on a run like "
             "this one): the final model refitted with the features a board computes from "
             "past samples only"
             + (" (" + "; ".join(f"{n}: {CAUSAL_FORMS[n]}" for n in on_chip["causal_forms"])
                + ")" if on_chip["causal_forms"] else "")
             + (", without " + ", ".join(on_chip["not_applied"]) + " (not applied on the "
                "board)" if on_chip["not_applied"] else "") + ", held-out p99 % FS: "
             + " ".join(f"{a} {v:.2f}" for a, v in zip(AXES, on_chip["heldout_p99_pct"]))
             + "."]
    return lines


def _format_params(params: dict) -> str:
    parts = []
    for key, value in params.items():
        if isinstance(value, list):
            parts.append(f"{key} = [" + ", ".join(f"{v:.4g}" for v in value) + "]")
        else:
            parts.append(f"{key} = {value:.4g}")
    return "; ".join(parts)


def _leftover_section(result: dict) -> list[str]:
    left = result["unexplained"]["verdict"]
    lines = ["## What is left", "",
             "Held-out residual after the ladder against the noise floor (white noise, from the "
             "residual's sample-to-sample differences), % FS rms:", ""]
    lines += _table(["", *AXES], [_row("left", left["rms_pct"], "{:.3f}"),
                                  _row("noise floor", left["noise_rms_pct"], "{:.3f}"),
                                  _row("variance / noise", left["excess_over_noise"])])
    lines += ["", "Per joint, the leftover as a joint torque (mN*m rms) and the share of its "
              "structured part each shape explains:", ""]
    shapes = list(result["unexplained"]["verdict"]["per_joint"][0]["shares"])
    lines += _table(["joint", "left", "noise", *shapes, "shape"], [
        f"| {r['joint']} | {1e3 * r['leftover_rms_nm']:.2f} | {1e3 * r['noise_rms_nm']:.2f} | "
        + " | ".join(f"{r['shares'][k]:.2f}" for k in shapes) + f" | {r['best'] or '-'} |"
        for r in left["per_joint"]])
    cart = left["cartesian"]
    lines += ["", f"Leftover force explained by the plate's position (affine + quadratic): "
              f"{cart['share']:.2f} (by each joint's own angle: "
              f"{cart.get('separable_share', 0.0):.2f}).", ""]
    return lines


def _excitation_section(result: dict) -> list[str]:
    ex = result["excitation"]
    lines = ["## Does the log excite each effect?", "",
             "z: how many noise standard errors a plausible-size parameter stands out by "
             f"(excited from {ex['thresholds']['excited_z']:g}, weak from "
             f"{ex['thresholds']['weak_z']:g}); fold support: the smallest share of it in any "
             "fold's training blocks.", ""]
    rows = []
    for name, joints in ex["families"].items():
        rows.append(f"| {name} | " + "; ".join(
            f"{j}: {v['level']} (z {v['z']:.0f}, {v['fold_support']:.2f})"
            for j, v in joints.items()) + " |")
    lines += _table(["family", "per joint"], rows)
    axes = ex["axes"]
    lines += ["", "Load per axis (p95 of |reference| / FS) and the smallest share of it in any "
              "fold's training blocks: " + ", ".join(
                  f"{a} {v:.2f}/{w:.2f}" for a, v, w in zip(AXES, axes["p95_load_fs"],
                                                           axes["training_share_min"])) + ".",
              ""]
    return lines


def _plot_ladder(plt, result):
    fig, ax = plt.subplots(figsize=(7, 3.6))
    labels = ["analytical"] + [f"+ {s['added']}" for s in result["ladder"]]
    values = [result["baseline_heldout_p99_pct"]] + [s["heldout_p99_pct"]
                                                     for s in result["ladder"]]
    values = np.array(values)
    for i, axis in enumerate(AXES):
        ax.plot(range(len(labels)), values[:, i], marker="o", label=axis)
    ax.set_xticks(range(len(labels)), labels, rotation=20, ha="right")
    ax.set_ylabel("held-out p99 error, % FS")
    ax.set_title("How far the gap shrinks")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(ncol=6, fontsize=8)
    return fig


def _plot_cross_axis(plt, result):
    before = np.array(result["where"]["cross_axis"]["matrix"])
    after = np.array(result["unexplained"]["cross_axis"]["matrix"])
    lim = max(np.abs(before).max(), np.abs(after).max(), 1e-6)
    fig, axes = plt.subplots(1, 2, figsize=(9, 4))
    for ax, mat, title in ((axes[0], before, "analytical"), (axes[1], after, "compensated")):
        im = ax.imshow(mat, cmap="RdBu_r", vmin=-lim, vmax=lim)
        ax.set_xticks(range(6), AXES)
        ax.set_yticks(range(6), AXES)
        ax.set_xlabel("residual axis")
        ax.set_ylabel("reference axis")
        ax.set_title(f"{title}: mean |off-diag| "
                     f"{np.abs(mat[~np.eye(6, dtype=bool)]).mean():.3f}")
        for i in range(6):
            for j in range(6):
                ax.text(j, i, f"{mat[i, j]:.3f}", ha="center", va="center", fontsize=6)
    fig.colorbar(im, ax=axes, shrink=0.8, label="FS/FS")
    return fig


def _plot_loops(plt, data: GapData):
    rng = np.random.default_rng(0)
    idx = np.sort(rng.choice(len(data), size=min(len(data), 6000), replace=False))
    tau = data.joint_torque_of(data.residual[idx], idx)
    vel = data.smooth_velocity[idx]
    fig, axes = plt.subplots(2, 3, figsize=(11, 6), sharex=True)
    for j, ax in enumerate(axes.flat):
        up = vel[:, j] > 0
        ax.scatter(data.theta[idx, j][up], 1e3 * tau[up, j], s=2, alpha=0.5, label="rising")
        ax.scatter(data.theta[idx, j][~up], 1e3 * tau[~up, j], s=2, alpha=0.5,
                   label="falling")
        ax.set_title(f"joint {j + 1}")
        ax.grid(alpha=0.3)
        if j % 3 == 0:
            ax.set_ylabel("residual as joint torque, mN*m")
        if j >= 3:
            ax.set_xlabel("theta_e, rad")
    axes.flat[0].legend(markerscale=4, fontsize=8)
    fig.suptitle("Residual vs motion direction (analytical model)")
    return fig


def _plot_breakdown(plt, result):
    where = result["where"]
    panels = [("speed", "joint speed"), ("direction", "direction")]
    panels.append(("time", "time"))
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for ax, (key, title) in zip(axes, panels):
        rows = where[key]["segments"] if key == "time" else where[key]
        p99 = np.array([[np.nan if v is None else v for v in r["p99"]] for r in rows])
        for i, axis in enumerate(AXES):
            ax.plot(range(len(rows)), p99[:, i], marker=".", label=axis)
        ax.set_xticks(range(len(rows)), [r["bin"] for r in rows], rotation=30, ha="right",
                      fontsize=7)
        ax.set_title(f"p99 by {title}")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("% FS")
    axes[0].legend(ncol=2, fontsize=7)
    return fig


def _plot_candidates(plt, result):
    cands = result["candidates"]
    fig, ax = plt.subplots(figsize=(7, 3.2))
    names = [c["name"] for c in cands]
    scores = np.array([c["score"] for c in cands])
    lo = np.array([c["score_ci"][0] for c in cands])
    hi = np.array([c["score_ci"][1] for c in cands])
    colors = ["tab:red" if n in result["present"] else "tab:gray" for n in names]
    ax.barh(names, scores, xerr=[scores - lo, hi - scores], color=colors)
    ax.invert_yaxis()
    ax.set_xlabel("share of held-out squared error removed (alone)")
    ax.set_title("Candidates (red: present)")
    ax.grid(alpha=0.3, axis="x")
    return fig
