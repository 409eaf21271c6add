"""``delta6 train --target mcu``: a small integer residual model for the microcontroller."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from delta6.commands._port import number
from delta6.core.errors import UserError
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.workspace import load_checked
from delta6.link.logfile import read_log

NAME = "train"
HELP = ("train a learned model on a calibration log; --target mcu: a quantized residual model "
        "the microcontroller runs (JSON, for delta6 codegen --model), with its float network "
        "as ONNX next to it")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="calibration log with t, theta_e1..6 and "
                        "the reference wrench Fx..Mz (docs/log-format.md)")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="the design the log was recorded with (default: the paper's)")
    parser.add_argument("--target", choices=("mcu",), required=True,
                        help="mcu: an int8 residual model for the board (docs/ondevice-model.md)")
    parser.add_argument("--residual-over", default="analytical", metavar="BASE",
                        help="the model the residual corrects: 'analytical' (default)")
    parser.add_argument("--hidden", default="16", metavar="N[xM]",
                        help="hidden layer widths, e.g. 16 or 16x8 (default 16)")
    parser.add_argument("--name", help="model name, at most 23 characters (default: the "
                                       "output file's stem)")
    parser.add_argument("--seed", type=number("--seed", int, 0), default=0,
                        help="seed of the initial weights and the batch order (default 0)")
    parser.add_argument("--epochs", type=number("--epochs", int, 1), default=30, metavar="N",
                        help="at most N epochs (default 30; early stopping on a held-back part)")
    parser.add_argument("-o", "--output", required=True, metavar="MODEL.json", type=Path,
                        help="the model file (the float network goes to MODEL.onnx)")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


def _hidden(text: str) -> tuple[int, ...]:
    try:
        sizes = tuple(int(x) for x in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--hidden takes widths like 16 or 16x8, got {text!r}") from None
    if not sizes or any(not 1 <= s <= 48 for s in sizes) or len(sizes) > 4:
        raise UserError("--hidden: one to four layers of 1..48 neurons")
    return sizes


def run(args: argparse.Namespace) -> int:
    if args.residual_over != "analytical":
        raise UserError(f"--residual-over {args.residual_over}: only 'analytical' is available "
                        "in this version")
    hidden = _hidden(args.hidden)
    name = args.name or args.output.stem
    if not name or len(name) > 23 or not name.isascii() or not name.isprintable():
        raise UserError("--name: 1..23 printable ASCII characters")
    if args.output.suffix.lower() != ".json":
        raise UserError("-o: the model file is JSON (MODEL.json); the ONNX goes next to it")
    design = load_checked(args.design)
    log = read_log(args.log)
    try:
        import torch  # noqa: F401
    except ImportError:
        raise UserError("training needs torch: pip install -e '.[train]' (torch==2.13.0)") from None
    from delta6.core import residualmodel
    from delta6.learning import mcu
    say = None if args.quiet else (lambda text: print(f"  {text}", file=sys.stderr, flush=True))
    settings = mcu.McuSettings(hidden=hidden, epochs=args.epochs, seed=args.seed)
    result = mcu.train_mcu(log, design, mcu.AnalyticalBase(design), name=name,
                           settings=settings, progress=say, source=Path(args.log).name)
    path = residualmodel.save(result.model, args.output)
    onnx_path = mcu.export_onnx(result.float_net, args.output.with_suffix(".onnx"),
                                {"delta6_model": name,
                                 "delta6_model_hash": f"0x{result.model.hash32():08x}",
                                 "delta6_design_hash": f"0x{design.hash32():08x}",
                                 "inputs": "int8 engine feature values, see the JSON model"})
    r = result.report
    print(f"wrote {path} (model '{name}', hash 0x{result.model.hash32():08x}, {r['macs']} "
          f"multiply-accumulates per sample) and {onnx_path}")
    print(f"held-out p99 % FS ({r['heldout']}): Fx Fy Fz Mx My Mz")
    for key in ("base", "float", "int8"):
        print(f"  {key:<6} " + " ".join(f"{v:5.2f}" for v in r["heldout_p99_pct"][key]))
    print("  quantization loss (int8 - float) " +
          " ".join(f"{v:+.3f}" for v in r["quantization_loss_p99_pct"]))
    return 0
