"""``delta6 train``: a learned estimator from a calibration log, exported to ONNX."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from delta6.commands._port import Progress, number
from delta6.core import calibration as calibration_mod
from delta6.core.accuracy import format_table
from delta6.core.errors import UserError
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.workspace import load_checked
from delta6.learning.presets import KINDS, PRESETS, preset
from delta6.link.logfile import read_log

NAME = "train"
HELP = "train a learned wrench estimator on a calibration log and export it to ONNX"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="calibration log with t, theta_e1..6 and "
                        "the reference wrench Fx..Mz (docs/log-format.md)")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="the design the log was recorded with (default: the paper's)")
    parser.add_argument("--model", required=True, choices=KINDS,
                        help="network: mlp, lstm, gru or transformer")
    parser.add_argument("--residual-over", default="none", metavar="BASE",
                        help="learn only what BASE misses: 'analytical' (the paper's model) "
                             "or a calibration file CAL.toml (delta6 calibrate: the hybrid); "
                             "default: the whole wrench (end-to-end)")
    parser.add_argument("--preset", choices=tuple(PRESETS), default="default",
                        help="'paper': the paper's Table IV sizes and recipe (slow on a CPU); "
                             "'default': small models that train in minutes")
    parser.add_argument("--seed", type=number("--seed", int, 0), default=0,
                        help="seed of the initial weights and the batch order (default 0)")
    parser.add_argument("--epochs", type=number("--epochs", int, 1), metavar="N",
                        help="at most N epochs (default: the preset's)")
    parser.add_argument("--max-minutes", type=number("--max-minutes", low=0, low_open=True),
                        metavar="M", help="stop after about M minutes, keeping the best "
                                          "checkpoint so far")
    parser.add_argument("--threads", type=number("--threads", int, 1), default=1, metavar="N",
                        help="CPU threads for training (default 1: these networks are small, "
                             "and on a busy machine more threads wait more than they work)")
    parser.add_argument("-o", "--output", required=True, metavar="MODEL.onnx",
                        help="where to write the model")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


def run(args: argparse.Namespace) -> int:
    base, calibration = args.residual_over, None
    if base not in ("none", "analytical"):
        if not base.lower().endswith(".toml"):
            raise UserError(f"--residual-over {base}: 'analytical' or a calibration file "
                            "(CAL.toml)")
        calibration = calibration_mod.load(base)
        base = "calibration"
    folder = Path(args.output).resolve().parent
    if not folder.is_dir():     # before the minutes of training, not after
        raise UserError(f"cannot write {args.output}: no folder {folder}")
    design = load_checked(args.design)
    log = read_log(args.log)
    chosen = preset(args.preset, args.model)
    changes = {k: v for k, v in (("max_epochs", args.epochs), ("max_minutes", args.max_minutes))
               if v is not None}
    if changes:
        chosen = chosen.with_recipe(**changes)
    try:
        from delta6.learning import fit
    except ImportError as exc:
        raise UserError(f"training needs torch ({exc.name} is missing): pip install "
                        "'delta6[train]'") from None

    display = Progress(sys.stderr)

    def progress(r) -> None:
        if not args.quiet:
            display.show(f"epoch {r.epoch:>3}/{r.max_epochs}  train {r.train_loss:.5f}  "
                         f"held-out {r.holdout_loss:.5f}  best {r.best_loss:.5f} "
                         f"(epoch {r.best_epoch})  lr {r.lr:.1e}  {r.seconds:5.0f} s")

    try:
        fitted = fit.fit(log, design, chosen, base=base, calibration=calibration, seed=args.seed,
                         threads=args.threads, source=args.log, progress=progress)
    finally:
        display.end()
    diff = fit.write(fitted, args.output)
    s = fitted.card.training
    print(f"{args.output}: {fitted.card.describe()}")
    print(f"  {args.preset} preset, {s['parameters']} parameters, {s['epochs']} epochs in "
          f"{s['seconds']:.0f} s ({s['stopped']}); best epoch {s['best_epoch']}; ONNX equals "
          f"torch within {diff:.1e}")
    print(f"Held-out tail of the log ({s['holdout_rows']} rows), |error| % FS:")
    print(format_table(_rows(s["holdout_pct_fs"]), title=args.model))
    if s.get("holdout_base_pct_fs"):
        print(format_table(_rows(s["holdout_base_pct_fs"]),
                           title="calibrated" if calibration else args.residual_over))
    return 0


def _rows(table: dict) -> dict:
    return {{"p100": "max"}.get(k, k): v for k, v in table.items()}
