"""``delta6 convert``: a log from CSV to MCAP (ROS 2) or back, every column and header kept."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from delta6.commands._port import frame_id
from delta6.core.errors import UserError
from delta6.core.outputs import check_output_file
from delta6.link.logfile import OPTIONAL_COLUMNS, open_log_writer, read_log

NAME = "convert"
HELP = "convert a log between CSV and MCAP (ROS 2 bag); the format follows each file's name"
BLOCK_ROWS = 100_000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", metavar="IN", help="log to read (CSV or MCAP, either name)")
    parser.add_argument("output", metavar="OUT", help="log to write: MCAP if it ends in .mcap, "
                                                      "CSV otherwise")
    parser.add_argument("--frame-id", type=frame_id, metavar="ID",
                        help="frame id of the wrench messages (default: the log's, or delta6_e)")
    parser.add_argument("--force", action="store_true",
                        help="replace OUT if it exists (a log is not regenerable: refused "
                             "otherwise)")
    parser.add_argument("--complete-rows", action="store_true",
                        help="keep only the rows with every angle and wrench value (a stream's "
                             "failed reads leave them empty), for the commands that need "
                             "complete rows (diagnose, calibrate, train, evaluate); the time "
                             "gaps stay gaps")


def run(args: argparse.Namespace) -> int:
    source, output = Path(args.source), Path(args.output)
    if output.exists() and source.exists() and output.resolve() == source.resolve():
        raise UserError(f"{output}: the output would overwrite the log being read")
    check_output_file(output, "OUT", force=args.force)
    log = read_log(source, require_complete_rows=False)
    if log.ignored_columns:        # nothing dropped unsaid: the log format has no place for them
        print(f"note: column(s) {', '.join(log.ignored_columns)} of {source} are not part of "
              "the log format and are not carried over", file=sys.stderr)
    meta = {k: v for k, v in log.meta.items() if k != "schema"}   # the writer writes its own
    if args.frame_id is not None:
        meta["frame_id"] = args.frame_id
    optional = tuple(c for c in OPTIONAL_COLUMNS if getattr(log, c) is not None)
    keep = (np.isfinite(log.theta).all(axis=1) & np.isfinite(log.wrench).all(axis=1)
            if args.complete_rows else np.ones(len(log), dtype=bool))
    if not keep.any():
        raise UserError(f"{source}: no row has every angle and wrench value")
    with open_log_writer(output, meta, optional=optional) as writer:
        for start in range(0, len(log), BLOCK_ROWS):
            part = np.flatnonzero(keep[start:start + BLOCK_ROWS]) + start
            if len(part):
                writer.write_block(log.t[part], log.theta[part], log.wrench[part],
                                   **{c: getattr(log, c)[part] for c in optional})
    dropped = len(log) - int(keep.sum())
    print(f"{output}: {int(keep.sum())} samples, columns t, theta_e1..6, Fx..Mz"
          + "".join(f", {c}" for c in optional)
          + (f" ({dropped} incomplete rows left out)" if args.complete_rows else ""),
          file=sys.stderr)
    return 0
