"""``delta6 train``: a learned estimator from a calibration log, exported to ONNX; with
``--target mcu`` a small integer residual model the microcontroller runs (docs/ondevice-model.md)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from delta6.commands._port import Progress, number
from delta6.core import calibration as calibration_mod
from delta6.core.accuracy import format_table
from delta6.core.design import label_problem
from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.core.outputs import check_output_file, check_replaces_only, json_object, written_together
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.residualmodel import MAX_NAME
from delta6.core.workspace import load_checked
from delta6.diagnosis.data import check_log
from delta6.learning.presets import KINDS, PRESETS, preset
from delta6.link.logdata import require_reference_wrench
from delta6.link.logfile import read_log

NAME = "train"
TRAINS_ON_A_REFERENCE = "a model learns the reference sensor's wrench (docs/learning.md)"
HELP = ("train a learned wrench estimator on a calibration log and export it to ONNX; "
        "--target mcu: a quantized residual model the microcontroller runs (JSON, for "
        "delta6 codegen --model), with its float network as ONNX next to it")


#: The largest seed both torch.manual_seed and numpy's generators take (a larger one ended
#: in torch's overflow traceback).
MAX_SEED = 2**32 - 1
HOST_MODEL = "a host model of delta6 train (ONNX)"
MCU_MODEL = "an on-chip model of delta6 train --target mcu (JSON)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="calibration log with t, theta_e1..6 and "
                        "the reference wrench Fx..Mz (docs/log-format.md)")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="the design the log was recorded with (default: the paper's)")
    parser.add_argument("--target", choices=("host", "mcu"), default="host",
                        help="host (default): an ONNX estimator for the host; mcu: an int8 "
                             "residual model compiled into the firmware (docs/ondevice-model.md)")
    parser.add_argument("--model", choices=KINDS,
                        help="network: mlp, lstm, gru or transformer (required for --target "
                             "host)")
    parser.add_argument("--residual-over", default="none", metavar="BASE",
                        help="learn only what BASE misses: 'analytical' (the paper's model) "
                             "or a calibration file CAL.toml (delta6 calibrate: the hybrid); "
                             "default: the whole wrench (end-to-end)")
    parser.add_argument("--preset", choices=tuple(PRESETS),
                        help="'paper': the paper's Table IV sizes and recipe (slow on a CPU); "
                             "'default' (the default): small models that train in minutes")
    parser.add_argument("--seed", type=number("--seed", int, 0, MAX_SEED), default=0,
                        help="seed of the initial weights and the batch order (default 0)")
    parser.add_argument("--epochs", type=number("--epochs", int, 1), metavar="N",
                        help="at most N epochs (default: the preset's; --target mcu: 30, with "
                             "early stopping on a held-back part)")
    parser.add_argument("--max-minutes", type=number("--max-minutes", low=0, low_open=True),
                        metavar="M", help="stop after about M minutes, keeping the best "
                                          "checkpoint so far")
    parser.add_argument("--threads", type=number("--threads", int, 1), metavar="N",
                        help="CPU threads for training (default 1: these networks are small, "
                             "and on a busy machine more threads wait more than they work)")
    parser.add_argument("--hidden", metavar="N[xM]",
                        help="--target mcu: hidden layer widths, e.g. 16 or 16x8, or 0 for a "
                             "linear map (default 16 over analytical; over a calibration a "
                             "linear map of the counts)")
    parser.add_argument("--name", help=f"--target mcu: model name, at most {MAX_NAME} printable "
                                       "ASCII characters (the board reports it; default: the "
                                       f"output file's name without .json, cut to {MAX_NAME})")
    parser.add_argument("-o", "--output", required=True, metavar="MODEL.onnx",
                        help="where to write the model (--target mcu: MODEL.json, and the "
                             "float network to MODEL.onnx); an existing file is replaced only "
                             "if it is a model of that kind")
    parser.add_argument("--quiet", action="store_true", help="no progress display")


#: Options of one target that the other would ignore: refused instead, whatever their value.
HOST_ONLY = (("--model", lambda a: a.model is not None),
             ("--preset", lambda a: a.preset is not None),
             ("--max-minutes", lambda a: a.max_minutes is not None),
             ("--threads", lambda a: a.threads is not None))
MCU_ONLY = (("--hidden", lambda a: a.hidden is not None),
            ("--name", lambda a: a.name is not None))


def _refuse_other_target(args) -> None:
    other = MCU_ONLY if args.target == "host" else HOST_ONLY
    given = [option for option, used in other if used(args)]
    if given:
        what = "--target mcu" if args.target == "host" else "a host model (--target host)"
        raise UserError(f"{', '.join(given)}: only for {what}")


def run(args: argparse.Namespace) -> int:
    _refuse_other_target(args)
    args.preset = args.preset or "default"
    args.threads = args.threads or 1
    if args.target == "mcu":
        return run_mcu(args)
    if args.model is None:
        raise UserError("give the network with --model (mlp, lstm, gru or transformer), or "
                        "--target mcu")
    base, calibration = args.residual_over, None
    if base not in ("none", "analytical"):
        if not base.lower().endswith(".toml"):
            raise UserError(f"--residual-over {base}: 'analytical' or a calibration file "
                            "(CAL.toml)")
        calibration = calibration_mod.load(base)
        base = "calibration"
    check_output_file(args.output, "-o",    # before the minutes of training, not after
                      inputs=[args.log, args.design, args.residual_over])
    if Path(args.output).suffix.lower() != ".onnx":
        # ONNX bytes under another name: a MODEL.json would pass for an on-chip model file
        raise UserError("-o: a host model is an ONNX file (MODEL.onnx); the on-chip model "
                        "(JSON) is --target mcu")
    check_replaces_only(args.output, "-o", HOST_MODEL, is_host_model)
    design = load_checked(args.design)
    log = read_log(args.log)
    require_reference_wrench(log.meta, args.log, TRAINS_ON_A_REFERENCE)
    check_log(log, design, min_samples=1)
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
    if base != "analytical":
        print(format_table(_rows(s["holdout_analytical_pct_fs"]), title="analytical"))
    worse = worse_axes(s["holdout_pct_fs"]["p99"], s["holdout_analytical_pct_fs"]["p99"])
    if worse:
        print(f"note: on the held-out tail the model is worse than the analytical model on "
              f"{', '.join(worse)} (p99): a longer calibration run helps (docs/learning.md, "
              "\"how long to calibrate\")")
    return 0


def _rows(table: dict) -> dict:
    return {{"p100": "max"}.get(k, k): v for k, v in table.items()}


def _hidden(text: str) -> tuple[int, ...]:
    if text.strip() == "0":
        return ()
    try:
        sizes = tuple(int(x) for x in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--hidden takes widths like 16 or 16x8, got {text!r}") from None
    if not sizes or any(not 1 <= s <= 48 for s in sizes) or len(sizes) > 4:
        raise UserError("--hidden: 0 (linear) or one to four layers of 1..48 neurons")
    return sizes


def is_host_model(path: Path) -> bool:
    """An ONNX file with a model card: what host training writes (and may write again)."""
    from delta6.learning.card import PREFIX, onnx_metadata
    return PREFIX + "schema" in (onnx_metadata(path) or {})


def is_mcu_model(path: Path) -> bool:
    """A JSON file of the on-chip model's schema: what --target mcu writes (and may write
    again)."""
    from delta6.core.residualmodel import SCHEMA
    return (json_object(path) or {}).get("schema") == SCHEMA


def _check_companion(onnx_path: Path, output: Path) -> None:
    """The float network goes to MODEL.onnx: replace only an earlier on-chip export there, never
    a host model or any other file a user keeps under that name."""
    if not onnx_path.exists():
        return
    from delta6.learning.card import onnx_metadata
    if "delta6_model" not in (onnx_metadata(onnx_path) or {}):
        raise UserError(f"-o {output}: its float network would replace {onnx_path}, which is "
                        "not an on-chip model's (a host model of delta6 train?); give another "
                        "name")


def _mcu_base(args, design):
    """The base the on-chip residual corrects: the analytical model, or a unit's calibrated
    model (the board then runs the calibrated firmware, codegen --calibration)."""
    from delta6.learning import mcu
    over = args.residual_over
    if over in ("none", "analytical"):
        return mcu.AnalyticalBase(design)
    if not over.lower().endswith(".toml"):
        raise UserError(f"--residual-over {over}: 'analytical' or a calibration file (CAL.toml)")
    cal = calibration_mod.load(over)
    cal.check_design(design)
    return mcu.CalibratedBase(design, cal)


def run_mcu(args: argparse.Namespace) -> int:
    """``--target mcu``: fit, quantize and score the integer residual model; write it as JSON
    and its float network as ONNX."""
    hidden = None if args.hidden is None else _hidden(args.hidden)
    output = Path(args.output)
    # An empty --name is refused; the default is cut as a calibration's is (delta6 calibrate).
    name = output.stem[:MAX_NAME] if args.name is None else args.name
    problem = label_problem(name)
    if problem:     # before the training, not when the file is written
        raise UserError(f"--name: {problem}" + ("" if args.name is not None else
                                                " (the default is -o's file name without "
                                                f"its extension, cut to {MAX_NAME} "
                                                "characters)"))
    if output.suffix.lower() != ".json":
        raise UserError("-o: the model file is JSON (MODEL.json); the ONNX goes next to it")
    inputs = [args.log, args.design, args.residual_over]
    check_output_file(output, "-o", inputs=inputs)
    check_output_file(output.with_suffix(".onnx"), "-o", inputs=inputs)
    check_replaces_only(output, "-o", MCU_MODEL, is_mcu_model)
    _check_companion(output.with_suffix(".onnx"), output)
    design = load_checked(args.design)
    base = _mcu_base(args, design)
    log = read_log(args.log)
    require_reference_wrench(log.meta, args.log, TRAINS_ON_A_REFERENCE)
    check_log(log, design, min_samples=1)
    # the board runs this model on one design (and calibration): a log of another is refused
    calibration_mod.check_log_meta(log.meta, design, getattr(base, "calibration", None),
                                   source=str(args.log))
    try:
        import torch  # noqa: F401
    except ImportError:
        raise UserError("training needs torch: pip install -e '.[train]' (torch==2.13.0)") from None
    from delta6.core import residualmodel
    from delta6.learning import mcu
    say = None if args.quiet else (lambda text: print(f"  {text}", file=sys.stderr, flush=True))
    settings = mcu.default_settings(base, epochs=args.epochs or 30, seed=args.seed,
                                    **({} if hidden is None else {"hidden": hidden}))
    # Before the minutes of training: a model no firmware image runs at its rate is no use.
    residualmodel.check_cost(residualmodel.planned_macs(6 * len(settings.features),
                                                        settings.hidden),
                             design, getattr(base, "calibration", None),
                             f"--hidden {args.hidden}" if args.hidden else "the model")
    result = mcu.train_mcu(log, design, base, name=name, settings=settings, progress=say,
                           source=Path(args.log).name)
    path, onnx_path = output, output.with_suffix(".onnx")
    # Renamed together, the JSON last: a model JSON on disk always has its own ONNX.
    with written_together(onnx_path, path) as (onnx_tmp, json_tmp):
        mcu.export_onnx(result.float_net, onnx_tmp,
                        {"delta6_model": name,
                         "delta6_model_hash": f"0x{result.model.hash32():08x}",
                         "delta6_design_hash": f"0x{design.hash32():08x}",
                         "inputs": "int8 engine feature values, see the JSON model"})
        json_tmp.write_text(residualmodel.dumps(result.model), encoding="utf-8")
    r = result.report
    print(f"wrote {path} (model '{name}' over {base.name}, hash 0x{result.model.hash32():08x}, "
          f"{r['macs']} multiply-accumulates per sample) and {onnx_path}")
    print(f"held-out p99 % FS ({r['heldout']}): Fx Fy Fz Mx My Mz")
    for key in ("base", "float", "int8"):
        print(f"  {key:<6} " + " ".join(f"{v:5.2f}" for v in r["heldout_p99_pct"][key]))
    print("  quantization loss (int8 - float) " +
          " ".join(f"{v:+.3f}" for v in r["quantization_loss_p99_pct"]))
    worse = worse_axes(r["heldout_p99_pct"]["int8"], r["heldout_p99_pct"]["base"])
    if worse:
        print(f"note: on the held-out tail the int8 model is worse than its base ({base.name}) "
              f"on {', '.join(worse)} (p99): the board would stream a worse wrench with it; a "
              "longer calibration run or more epochs may help (docs/ondevice-model.md)")
    return 0


def worse_axes(model_p99, base_p99) -> list[str]:
    """The axes on which a model's held-out p99 is above its base's."""
    return [axis for axis, m, b in zip(AXES, model_p99, base_p99) if m > b]
