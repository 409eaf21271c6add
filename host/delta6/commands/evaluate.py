"""``delta6 evaluate``: the paper's Table V for the analytical model and, with a calibration,
the calibrated model, and learned estimators (``--model``), on a log with reference wrenches
(``delta6.evaluation.tablev``); ``--plot`` draws their error distributions."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from delta6.calibration.fit import check_rig_latency
from delta6.core import calibration as calibration_mod
from delta6.core.calibrated import CalibratedModel, speeds_beyond_calibration
from delta6.core.errors import UserError
from delta6.core.outputs import (
    check_output_file,
    check_replaces_only,
    check_same_outputs,
    json_object,
    write_text_atomically,
)
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.spec import full_scale
from delta6.core.workspace import load_checked
from delta6.diagnosis.data import check_log, errors_naming, frozen_stretches
from delta6.evaluation import tablev
from delta6.evaluation.error_plot import check_plot_path, plot_errors
from delta6.learning import LearnedEstimator
from delta6.learning.mcu import McuEstimator
from delta6.learning.windows import OFF_RATE, OFF_RATE_SHARE, nominal_rate, off_rate_share
from delta6.link.logdata import require_reference_wrench, unchecked_design_notes
from delta6.link.logfile import read_log

NAME = "evaluate"
HELP = ("Table V (p95, p99, max |error| per axis, % FS) of the analytical model, the "
        "calibrated model (--calibration) and learned estimators (--model) on a log with "
        "reference wrenches")

#: Under this many samples the percentiles of Table V say little more than its maximum.
FEW_SAMPLES = 200


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", metavar="LOG.csv", help="log with t, theta_e1..6, Fx..Mz "
                        "(docs/log-format.md)")
    parser.add_argument("--design", default=str(DEFAULT_DESIGN), metavar="DESIGN.toml",
                        help="the design the log was recorded with (default: the paper's, "
                             "designs/delta6.toml)")
    parser.add_argument("--calibration", metavar="CAL.toml",
                        help="also evaluate the calibrated model (delta6 calibrate)")
    parser.add_argument("--model", nargs="+", action="extend", default=[], metavar="M.onnx",
                        help="learned estimators (delta6 train), one row each, named after the "
                             "file; a residual over a calibration needs that --calibration; an "
                             "on-chip model (M.json, delta6 train --target mcu) runs through "
                             "the integer reference as the board runs it")
    parser.add_argument("--rig-latency", metavar="SECONDS|calibration",
                        help="score every row against the reference advanced by the "
                             "calibration rig's latency (linear interpolation; 'calibration': "
                             "the latency the --calibration fitted, fit.rig_latency_s); "
                             "default: the recorded reference")
    parser.add_argument("--json", metavar="OUT.json",
                        help="write the table as JSON (an existing file only if it is such a "
                             "table)")
    parser.add_argument("--plot", metavar="OUT.png",
                        help="plot the error distributions of every row, in the image format "
                             "the suffix names (needs matplotlib)")


#: The keys that make a JSON file an evaluate table (delta6.evaluation.tablev.table).
TABLE_KEYS = ("rows", "samples", "full_scale", "axes")


def is_table_json(path: Path) -> bool:
    """Whether ``path`` holds a table this command wrote: the one kind of file --json
    replaces (a twin's truth file or a model under that name stays)."""
    document = json_object(path)
    return document is not None and all(key in document for key in TABLE_KEYS)


def estimators(args, design, log, cal) -> list:
    """The rows: the analytical model always, the calibrated model with --calibration (``cal``,
    loaded), then each --model in the order given."""
    rows = [tablev.Analytical(design)]
    if cal is not None:
        calibration_mod.check_log_meta(log.meta, design, cal, source=str(args.log))
        rows.append(CalibratedModel(design, cal))
    else:
        calibration_mod.check_log_meta(log.meta, design, source=str(args.log))
    rows += [McuEstimator(path, design, cal) if Path(path).suffix.lower() == ".json"
             else LearnedEstimator(path, design=design, calibration=cal) for path in args.model]
    names = [r.name for r in rows]
    if len(set(names)) != len(names):
        raise UserError("two rows would share a name (rows are named after the model files): "
                        + ", ".join(names))
    return rows


class Computed:
    """An estimator whose predictions are already known (computed once for the table and
    the plot)."""

    def __init__(self, name: str, estimate):
        self.name, self.estimate = name, estimate

    def predict(self, log):
        return self.estimate


def mixed_rate_note(t) -> str | None:
    """A line when much of the log is at another rate than its median step's, the rate a
    model's window (or an on-chip model's stride) is matched to."""
    share = off_rate_share(t)
    if share <= OFF_RATE_SHARE:
        return None
    return (f"note: {share:.0%} of the log's time steps are more than {OFF_RATE:.0%} away from "
            f"its median step ({nominal_rate(t):.4g} Hz): the models see those windows at "
            "another rate than they were made for (a mixed-rate log, or many lost samples)")


def rig_latency(args, cal) -> float:
    """The latency the reference is advanced by (0: the recorded reference)."""
    if args.rig_latency is None:
        return 0.0
    if args.rig_latency == "calibration":
        if cal is None:
            raise UserError("--rig-latency calibration needs --calibration CAL.toml")
        fitted = cal.fit.get("rig_latency_s")
        if fitted is None:
            raise UserError(f"{args.calibration}: the calibration records no rig latency "
                            "(fit.rig_latency_s); give --rig-latency SECONDS")
        try:
            return check_rig_latency(fitted)
        except UserError as exc:
            raise UserError(f"{args.calibration}: fit.rig_latency_s: {exc}") from None
    return check_rig_latency(args.rig_latency)


def run(args: argparse.Namespace) -> int:
    if args.rig_latency not in (None, "calibration"):
        check_rig_latency(args.rig_latency)
    if args.json:
        check_output_file(args.json, "--json",
                          inputs=[args.log, args.design, args.calibration, *(args.model or [])])
        check_replaces_only(args.json, "--json", "a Table V of delta6 evaluate", is_table_json)
    if args.plot:
        check_plot_path(args.plot)
    check_same_outputs({"--json": args.json, "--plot": args.plot})
    design = load_checked(args.design)
    log = read_log(args.log)
    if len(log) == 0:
        raise UserError(f"{args.log}: no samples")
    require_reference_wrench(log.meta, args.log, "Table V compares the estimators with a "
                             "reference (docs/calibration.md)")
    # The diagnosis's checks (units, wrap-arounds, corrupt rows): a table of a broken log is
    # no figure.
    with errors_naming(args.log):
        check_log(log, design, min_samples=1)
    for note in unchecked_design_notes(log.meta, args.design) + frozen_stretches(log.t,
                                                                                 log.theta):
        print(note, file=sys.stderr)
    cal = calibration_mod.load(args.calibration) if args.calibration else None
    latency = rig_latency(args, cal)
    rows = [Computed(e.name, e.predict(log)) for e in estimators(args, design, log, cal)]
    # After the estimators' checks (the calibration's design, the log's header): a note on a
    # log that is then refused is noise.
    for note in speeds_beyond_calibration(cal, log.t, log.theta) if cal else []:
        print(note, file=sys.stderr)
    if args.model:
        note = mixed_rate_note(log.t)
        if note:
            print(note, file=sys.stderr)
    result = tablev.table(rows, log, design, rig_latency_s=latency)
    if args.json:
        write_text_atomically(args.json, json.dumps(result, indent=1) + "\n")
    if args.plot:
        reference, keep = tablev.advanced_reference(log, latency)
        plot_errors({r.name: r.estimate[keep] for r in rows}, reference, full_scale(design),
                    args.plot,
                    title=f"|error| distributions on {Path(args.log).name}")
    print(tablev.format_table(result))
    if len(log) < FEW_SAMPLES:
        print(f"note: {len(log)} samples: p95 and p99 are then close to the largest error; "
              "Table V wants a run of minutes", file=sys.stderr)
    return 0
