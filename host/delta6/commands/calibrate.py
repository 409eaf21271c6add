"""``delta6 calibrate``: fit a unit's calibration from a calibration log (docs/calibration.md)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from delta6.calibration import calibrate
from delta6.calibration.fit import check_effects, check_rig_latency
from delta6.calibration.report import corrected, write_report
from delta6.commands._port import number
from delta6.core import calibration as calibration_mod
from delta6.core.calibration import CORRECTED, NAME_LIMIT
from delta6.core.design import label_problem
from delta6.core.errors import UserError
from delta6.core.model import AXES
from delta6.core.outputs import check_output_file, check_output_folder
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.workspace import load_checked
from delta6.diagnosis.data import (
    check_log,
    check_motion,
    errors_naming,
    frozen_stretches,
)
from delta6.link.logdata import unchecked_design_notes, wrench_from_device
from delta6.link.logfile import read_log

NAME = "calibrate"
HELP = "fit a calibration (corrections to the analytical model) for one unit from a log"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="calibration log with t, theta_e1..6, "
                        "Fx..Mz (docs/log-format.md)")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="the design the log was recorded with (default: the paper's, "
                             "designs/delta6.toml)")
    parser.add_argument("-o", "--output", required=True, metavar="CAL.toml",
                        help="calibration file to write")
    parser.add_argument("--effect", action="append", metavar="NAME",
                        help="correct this effect (repeatable; default: what the gap diagnosis "
                             f"finds). One of {', '.join(CORRECTED)}; the rig's latency "
                             "(sensor_latency) is always fitted, never applied")
    parser.add_argument("--rig-latency", metavar="SECONDS",
                        help="the calibration rig's known latency (its reference wrench is "
                             "paired with the encoders this late; 0: none), used instead of "
                             "fitting it (default: fitted, 0..0.2 s)")
    parser.add_argument("--name", metavar="NAME",
                        help=f"the calibration's name (at most {NAME_LIMIT} printable ASCII "
                             "characters; the board reports it); default: the output file's "
                             f"name without .toml, cut to {NAME_LIMIT} characters")
    parser.add_argument("--report", metavar="OUT_DIR",
                        help="write a Markdown report with plots into this directory")
    parser.add_argument("--every", type=number("--every", int, 1, 10_000), default=1,
                        metavar="K",
                        help="fit on every K-th sample (the log read at 1/K of its rate: a "
                             "long or fast log in less memory; the calibration is defined in "
                             "time, the board applies it at its own rate)")
    parser.add_argument("--seed", type=number("--seed", int, 0), default=0, metavar="N",
                        help="seed of the block bootstrap (default 0)")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")


def run(args: argparse.Namespace) -> int:
    out = check_output_file(args.output, "-o",       # before the fit, not after it
                            inputs=[args.log, args.design])
    if args.report:
        check_output_folder(args.report, "--report")
    twice = sorted({e for e in args.effect or [] if args.effect.count(e) > 1})
    if twice:
        raise UserError(f"--effect {', '.join(twice)} given twice")
    if "sensor_latency" in (args.effect or []):
        # Always fitted as the rig's and never corrected on the board: named alone it asked
        # for an identity calibration.
        raise UserError("--effect sensor_latency: the rig's latency is always fitted, never "
                        "corrected on the board; name the effects to correct (--rig-latency "
                        "states a known one)")
    if args.effect:
        check_effects(args.effect)                        # before the log is read
    design = load_checked(args.design)
    latency = None if args.rig_latency is None else check_rig_latency(args.rig_latency)
    name = (out.name.removesuffix(".toml")[:NAME_LIMIT] if args.name is None else args.name)
    problem = label_problem(name)
    if problem:         # before the fit, not when the file is written
        raise UserError(f"--name: {problem}" + ("" if args.name is not None else
                                                " (the default is -o's file name without "
                                                f".toml, cut to {NAME_LIMIT} characters)"))
    log = read_log(args.log).every(args.every)
    check_memory(len(log), args.every)
    if wrench_from_device(log.meta):
        raise UserError(f"{args.log}: the wrench in this log is the device's own model output "
                        "(a device log), not a reference sensor's: a calibration is fitted "
                        "against a reference (docs/calibration.md)")
    calibration_mod.check_log_meta(log.meta, design, source=str(args.log))
    thinned = f" (after --every {args.every}: the log's every {args.every}th sample)" \
        if args.every > 1 else ""
    with errors_naming(str(args.log) + thinned):
        check_log(log, design)                            # (its notes below need a sound log)
    check_motion(log.theta, str(args.log), why="a calibration cannot fit a joint it never saw "
                                               "move")
    for note in (unchecked_design_notes(log.meta, args.design) + frozen_stretches(log.t, log.theta)
                 + short_log_notes(log.t)):
        print(note, file=sys.stderr)

    def progress(message: str) -> None:
        if not args.quiet:
            print(f"  {message}", file=sys.stderr, flush=True)

    with errors_naming(args.log):
        fit = calibrate(log, design, effects=args.effect, name=name,
                        source=Path(args.log).name, seed=args.seed, rig_latency_s=latency,
                        progress=progress)
    calibration_mod.save(fit.calibration, out)
    if args.report:
        path = write_report(fit, log, design, args.report, source=str(args.log))
        progress(f"report: {path}")
    print(summary(fit, out))
    return 0


#: What the fit holds: a fixed part (the interpreter, the libraries, the diagnosis's state)
#: and per sample of the log (its columns, the model's response to each parameter, the
#: held-out copies). Peak resident memory measured on the paper unit: 20,000 samples 0.55 GB,
#: 10^5 2.13 GB (19.7 KB a sample beyond 0.16 GB); an outside review: 30,000 1.0 GB, 60,000
#: 1.31 GB, 400,000 7.1 GB. These bounds hold every one of them.
FIT_BASE_BYTES = 400_000_000
FIT_BYTES_PER_SAMPLE = 21_000


def fit_memory(samples: int) -> int:
    """Bytes the fit of a log of ``samples`` samples needs, at most (as measured)."""
    return FIT_BASE_BYTES + samples * FIT_BYTES_PER_SAMPLE


def available_memory() -> int | None:
    """Bytes of memory the system can give without swapping (None: not known here)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def check_memory(samples: int, every: int, available: int | None = None) -> None:
    """Refuse, in one line and before the minutes of work, a fit the memory cannot hold (the
    system would kill it halfway)."""
    available = available_memory() if available is None else available
    need = fit_memory(samples)
    if available is None or need <= available:
        return
    fits = (available - FIT_BASE_BYTES) // FIT_BYTES_PER_SAMPLE     # samples that fit
    if fits < 2000:
        raise UserError(f"fitting {samples} samples needs about {need / 1e9:.1f} GB of memory "
                        f"and {available / 1e9:.1f} GB are available: too little for any fit "
                        "(close other programs)")
    k = every * -(-samples // fits)         # every k-th sample: ceil(samples / k) <= fits
    raise UserError(f"fitting {samples} samples needs about {need / 1e9:.1f} GB of memory and "
                    f"{available / 1e9:.1f} GB are available: pass --every {k} (the log read "
                    f"at 1/{k} of its rate)")


def summary(fit, out: Path) -> str:
    cal = fit.calibration

    def row(label, values):
        return f"  {label:<22}" + "".join(f"{v:>8.2f}" for v in values)

    lines = [f"wrote {out}: calibration '{cal.name}' (hash 0x{cal.hash32():08x}) for design "
             f"'{cal.design_name}' (0x{cal.design_hash:08x}), fitted in {fit.seconds:.1f} s",
             "corrects: " + corrected(fit)]
    how = ("as stated" if fit.latency_given
           else "fitted, at its lower bound: no delay found" if fit.latency_s <= 0 else "fitted")
    lines.append(f"rig latency {1e3 * fit.latency_s:.1f} ms ({how}): the reference's, not "
                 "applied on the board")
    lines += [f"  {n}" for n in fit.notes]
    lines.append("held-out p99 |error|, % FS:" )
    lines.append(f"  {'':<22}" + "".join(f"{a:>8}" for a in AXES))
    lines.append(row("analytical", fit.heldout_before["p99_pct"]))
    lines.append(row("calibrated", fit.heldout_after["p99_pct"]))
    if fit.latency_s > 0 and fit.heldout_after_rig is not None:
        # The board's wrench is not late; the recorded reference is.
        lines.append(f"  against the reference {1e3 * fit.latency_s:.1f} ms later "
                     "(evaluate --rig-latency calibration):")
        lines.append(row("analytical", fit.heldout_before_rig["p99_pct"]))
        lines.append(row("calibrated", fit.heldout_after_rig["p99_pct"]))
    return "\n".join(lines)


#: Under this many seconds of log a calibration is fitted and scored on too little motion (on
#: the twin, 200 s calibrate as well as 2000 s; 10 s at 250 Hz passed the sample count but
#: calibrated twice as badly).
SHORT_LOG_S = 60.0


def short_log_notes(t) -> list[str]:
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    if span >= SHORT_LOG_S:
        return []
    return [f"note: the log covers {span:.3g} s: its held-out figures rest on a few seconds of "
            "motion; a calibration wants minutes (200 s calibrate the twin as well as 2000 s)"]
