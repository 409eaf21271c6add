"""``delta6 decode``: turn a raw byte capture of the stream into a log (docs/log-format.md).

A capture may hold more than one device session (the device restarted, or captures were
joined): each is a log of its own, since a log's time must increase and the counters start
again at a restart. ``--session`` picks one; the summary says how many there are.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from delta6.commands._port import Progress, flagged, log_meta, number
from delta6.core.design import load
from delta6.core.errors import UserError
from delta6.core.outputs import check_output_file
from delta6.link.bulkdecode import Capture, decode_capture, sequence_counts
from delta6.link.infocheck import info_problem
from delta6.link.logfile import open_log_writer
from delta6.link.protocol import Info, impossible_counts
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
    parser.add_argument("--session", type=number("--session", int, 1), default=1, metavar="N",
                        help="which device session of the capture to decode (default 1: the "
                             "first; a restart of the device starts a new one)")
    parser.add_argument("--force", action="store_true", help="replace an existing FILE")


def run(args: argparse.Namespace) -> int:
    check_output_file(args.output, "-o", force=args.force, partial=True,
                      inputs=[args.capture, args.design])
    path = Path(args.capture)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise UserError(f"{path}: is a folder, not a capture") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot be read ({exc.strerror})") from None
    design = load(args.design) if args.design else None
    capture = decode_capture(data)
    if not len(capture):
        raise UserError(f"{path}: no data records in {len(data)} bytes "
                        f"({capture.stats.resyncs} damaged frames)")
    sessions = capture.sessions
    if args.session > len(sessions):
        raise UserError(f"{path}: --session {args.session}, but the capture holds "
                        f"{len(sessions)} session{'s' * (len(sessions) > 1)}")
    rows = sessions[args.session - 1]
    infos = _session_infos(capture, rows)
    for frame, info in infos:
        problem = info_problem(info)
        if problem is not None:
            raise UserError(f"{path}: the device-info record at frame {frame} is unusable: "
                            f"{problem}")
    if infos:
        info = infos[-1][1]          # the scale never changes; mode and tare may have
        if design is not None and design.hash32() != info.design_hash:
            raise UserError(f"{path}: recorded from design hash 0x{info.design_hash:08x}, but "
                            f"{args.design} has hash 0x{design.hash32():08x}")
        lsb = info.lsb
        meta = log_meta(info, path.name, "delta6 decode")
        zero = _zero_per_row(capture, rows, infos)
    elif design is not None:
        lsb = design_lsb(design)
        meta = {"design": design.name, "design_hash": f"0x{design.hash32():08x}",
                "source": f"delta6 decode {path.name}", "wrench_source": "device",
                "lsb": " ".join(f"{v:g}" for v in lsb)}
        zero = None
    else:
        raise UserError(f"{path}: the capture holds no device-info record"
                        + (f" in session {args.session}" if len(sessions) > 1 else "")
                        + ", so the wrench scale is unknown: pass --design DESIGN.toml")
    time_us = capture.time_us[rows]
    period = float(np.median(np.diff(time_us))) if len(time_us) > 1 else 0.0
    if period > 0:      # what the device ran at, measured: the median period
        meta["rate_hz"] = int(round(1e6 / period))
    if len(sessions) > 1:
        meta["session"] = f"{args.session} of {len(sessions)}"
    has_counts = capture.has_counts[rows]
    meta["mode"] = ("wrench_raw" if has_counts.all() else "wrench" if not has_counts.any()
                    else "mixed")
    n = len(time_us)
    wrench = capture.wrench(lsb)[rows]
    theta = capture.theta(zero)[rows] if zero is not None and has_counts.any() else None
    status = capture.status[rows]
    seq = capture.seq[rows]
    progress = Progress()
    with open_log_writer(args.output, meta, optional=("seq", "status"),
                         overwrite=args.force) as log:
        for start in range(0, n, BLOCK_ROWS):
            part = slice(start, min(start + BLOCK_ROWS, n))
            # / 1e6, not * 1e-6: the double nearest each microsecond's decimal.
            log.write_block(time_us[part] / 1e6, None if theta is None else theta[part],
                            wrench[part], seq=seq[part], status=status[part])
            if n > BLOCK_ROWS:
                progress.show(f"{part.stop} / {n} rows")
    progress.end()
    s = capture.stats
    gaps, lost = sequence_counts(seq)
    impossible = int(impossible_counts(capture.counts[rows]).sum())
    unknown = f", {s.unknown_types} records of unknown type ignored" if s.unknown_types else ""
    print(f"{args.output}: {n} samples, {lost} missing in {gaps} gaps, {flagged(status)} "
          f"flagged, {s.resyncs} damaged frames ({s.recovered} records recovered), "
          f"{s.bytes_discarded} bytes discarded, {capture.duplicates} duplicates{unknown}"
          + (f", {impossible} impossible encoder counts left empty" if impossible else "")
          + ("" if theta is not None or zero is None else "; no raw counts: angles left empty")
          + ("" if infos else "; no device info: angles left empty")
          + (f"; the capture ends {capture.trailing_bytes} bytes into an unfinished frame"
             if capture.trailing_bytes else "")
          + _sessions_note(capture, args.session), file=sys.stderr)
    return 0


def _session_infos(capture: Capture, rows: slice) -> list[tuple[int, Info]]:
    """The info records of a session: those whose next data record belongs to it (the info a
    device sends at boot comes before its first data record)."""
    frames = capture.frame_index
    out = []
    for frame, record in capture.other:
        if isinstance(record, Info):
            row = min(int(np.searchsorted(frames, frame)), len(frames) - 1)
            if rows.start <= row < rows.stop:
                out.append((frame, record))
    return out


def _zero_per_row(capture: Capture, rows: slice, infos) -> np.ndarray:
    """The zero counts in force for each row: from the session's latest info before it
    (its first info for rows before any)."""
    at = np.array([frame for frame, _ in infos])
    zeros = np.array([info.zero_counts for _, info in infos])
    which = np.clip(np.searchsorted(at, capture.frame_index, side="right") - 1, 0, None)
    full = np.zeros((len(capture), 6), dtype=np.int64)
    full[rows] = zeros[which[rows]]
    return full


def _sessions_note(capture: Capture, chosen: int) -> str:
    sessions = capture.sessions
    if len(sessions) == 1:
        return ""
    sizes = ", ".join(f"{i + 1}: {s.stop - s.start} samples" for i, s in enumerate(sessions))
    how = (f", {capture.unannounced_restarts} of them found by counters that began again"
           if capture.unannounced_restarts else "")
    return (f"; the capture holds {len(sessions)} device sessions (the device restarted"
            f"{how}; {sizes}): this log has session {chosen}, --session N decodes another")
