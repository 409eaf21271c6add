"""``delta6 decode``: turn a raw byte capture of the stream into a log (docs/log-format.md)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from delta6.commands._port import Progress, log_meta
from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.link.bulkdecode import decode_capture, sequence_counts
from delta6.link.logfile import open_log_writer
from delta6.link.protocol import Event, EventCode
from delta6.link.wirescale import design_lsb

NAME = "decode"
HELP = "decode a raw capture of the device's byte stream into a log (CSV or MCAP)"
BLOCK_ROWS = 100_000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("capture", metavar="CAPTURE.bin", help="raw bytes as received")
    parser.add_argument("-o", "--output", required=True, metavar="FILE",
                        help="log file: CSV, or MCAP (ROS 2) when it ends in .mcap")
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
    rows, restart_note = _before_restart(capture)
    has_counts = capture.has_counts[:rows]
    meta["mode"] = ("wrench_raw" if has_counts.all() else "wrench" if not has_counts.any()
                    else "mixed")
    wrench = capture.wrench(lsb)[:rows]
    theta = (capture.theta(zero)[:rows] if zero is not None and has_counts.any() else None)
    progress = Progress()
    with open_log_writer(args.output, meta, optional=("seq", "status")) as log:
        for start in range(0, rows, BLOCK_ROWS):
            part = slice(start, min(start + BLOCK_ROWS, rows))
            log.write_block(capture.time_us[part] * 1e-6,
                            None if theta is None else theta[part], wrench[part],
                            seq=capture.seq[part], status=capture.status[part])
            if rows > BLOCK_ROWS:
                progress.show(f"{part.stop} / {rows} rows")
    progress.end()
    s = capture.stats
    gaps, lost = sequence_counts(capture.seq[:rows])    # before the restart, if one cut it
    print(f"{args.output}: {rows} samples, {lost} missing in {gaps} "
          f"gaps, {s.resyncs} damaged frames ({s.recovered} records recovered), "
          f"{s.bytes_discarded} bytes discarded, {capture.duplicates} duplicates"
          + ("" if theta is not None or zero is None else "; no raw counts: angles left empty")
          + ("" if infos else "; no device info: angles left empty") + restart_note,
          file=sys.stderr)
    return 0


def _before_restart(capture) -> tuple[int, str]:
    """Rows before the first device restart that has data on both sides (a log's time must
    increase; the device's clock starts again at a reboot)."""
    boots = [i for i, r in capture.other if isinstance(r, Event) and r.code == EventCode.BOOT]
    for frame in boots:
        rows = int(np.searchsorted(capture.frame_index, frame))
        if 0 < rows < len(capture):
            return rows, (f"; the device restarted at frame {frame}: the {len(capture) - rows} "
                          "samples after it are not in this log (decode the rest of the "
                          "capture separately)")
    return len(capture), ""


def _zero_per_row(capture) -> np.ndarray:
    """The zero counts in force for each row: from the latest info record before it."""
    infos = [(i, r) for i, r in capture.other if hasattr(r, "zero_counts")]
    at = np.array([i for i, _ in infos])
    zeros = np.array([r.zero_counts for _, r in infos])
    which = np.clip(np.searchsorted(at, capture.frame_index, side="right") - 1, 0, None)
    return zeros[which]
