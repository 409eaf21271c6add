"""``delta6 decode``: turn a raw byte capture of the stream into a log (docs/log-format.md)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..bulkdecode import decode_capture
from ..design import load
from ..errors import UserError
from ..logfile import LogWriter
from ..wirescale import design_lsb
from ._port import Progress, log_meta

NAME = "decode"
HELP = "decode a raw capture of the device's byte stream into a CSV log"
BLOCK_ROWS = 100_000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("capture", metavar="CAPTURE.bin", help="raw bytes as received")
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="log file (CSV)")
    parser.add_argument("--design", metavar="DESIGN.toml",
                        help="the device's design file: gives the wrench scale when the capture "
                             "holds no device-info record, and is checked against it otherwise")


def run(args: argparse.Namespace) -> int:
    path = Path(args.capture)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot be read ({exc.strerror})") from None
    capture = decode_capture(data)
    if not len(capture):
        raise UserError(f"{path}: no data records in {len(data)} bytes "
                        f"({capture.stats.resyncs} damaged frames)")
    infos = capture.infos
    design = load(args.design) if args.design else None
    if infos:
        info = infos[-1]          # the scale never changes; mode and tare may have
        if design is not None and design.hash32() != info.design_hash:
            raise UserError(f"{path}: recorded from design hash 0x{info.design_hash:08x}, but "
                            f"{args.design} has hash 0x{design.hash32():08x}")
        lsb = info.lsb
        meta = log_meta(info, path.name, "delta6 decode")
        zero = _zero_per_row(capture)
    elif design is not None:
        lsb = design_lsb(design)
        meta = {"design": design.name, "design_hash": f"0x{design.hash32():08x}",
                "source": f"delta6 decode {path.name}",
                "lsb": " ".join(f"{v:g}" for v in lsb)}
        zero = None
    else:
        raise UserError(f"{path}: the capture holds no device-info record, so the wrench scale "
                        "is unknown: pass --design DESIGN.toml")
    has_counts = capture.has_counts
    meta["mode"] = ("wrench_raw" if has_counts.all() else "wrench" if not has_counts.any()
                    else "mixed")
    wrench = capture.wrench(lsb)
    theta = capture.theta(zero) if zero is not None and has_counts.any() else None
    progress = Progress()
    with LogWriter(args.output, meta, optional=("seq", "status")) as log:
        for start in range(0, len(capture), BLOCK_ROWS):
            rows = slice(start, start + BLOCK_ROWS)
            log.write_block(capture.time_us[rows] * 1e-6,
                            None if theta is None else theta[rows], wrench[rows],
                            seq=capture.seq[rows], status=capture.status[rows])
            if len(capture) > BLOCK_ROWS:
                progress.show(f"{min(start + BLOCK_ROWS, len(capture))} / {len(capture)} rows")
    progress.end()
    s = capture.stats
    print(f"{args.output}: {len(capture)} samples, {capture.lost} missing in {capture.gaps} "
          f"gaps, {s.resyncs} damaged frames ({s.recovered} records recovered), "
          f"{s.bytes_discarded} bytes discarded, {capture.duplicates} duplicates"
          + ("" if theta is not None or zero is None else "; no raw counts: angles left empty")
          + ("" if infos else "; no device info: angles left empty"), file=sys.stderr)
    return 0


def _zero_per_row(capture) -> np.ndarray:
    """The zero counts in force for each row: from the latest info record before it."""
    infos = [(i, r) for i, r in capture.other if hasattr(r, "zero_counts")]
    at = np.array([i for i, _ in infos])
    zeros = np.array([r.zero_counts for _, r in infos])
    which = np.clip(np.searchsorted(at, capture.frame_index, side="right") - 1, 0, None)
    return zeros[which]
