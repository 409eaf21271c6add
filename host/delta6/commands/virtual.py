"""``delta6 virtual``: the virtual board, the firmware on an emulated ATmega328P with six
emulated encoders, on a pseudo-terminal that every other command can open (docs/virtual-board.md).
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

from delta6.build.avrbuild import NANO
from delta6.commands._port import number
from delta6.commands._signals import STOP_SIGNALS
from delta6.core.design import DEFAULT_DESIGN
from delta6.core.errors import UserError
from delta6.core.outputs import check_output_file
from delta6.link.protocol import theta_to_counts, valid_counts
from delta6.sim import virtualboard as vb

NAME = "virtual"
#: The twin's sample rate when it drives the board: above any rate the board samples at.
TWIN_RATE_HZ = 1000.0
HELP = ("run the virtual board (the firmware on an emulated ATmega328P with six emulated "
        "encoders); prints its port, then runs until Ctrl-C")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--design", metavar="DESIGN.toml", type=Path,
                        help="build the firmware for this design (default: the committed "
                             "header, designs/delta6.toml)")
    parser.add_argument("--calibration", metavar="CAL.toml", type=Path,
                        help="run the firmware with this unit's calibration compiled in "
                             "(delta6 calibrate; with --design, or the default design)")
    parser.add_argument("--model", metavar="MODEL.json", type=Path,
                        help="compile this on-chip residual model (delta6 train --target mcu) "
                             "into the firmware, over the calibration when one is given (with --design, "
                             "or the default design)")
    motion = parser.add_mutually_exclusive_group()
    motion.add_argument("--replay", metavar="LOG.csv", type=Path,
                        help="encoder angles over time: a log with t and theta_e1..6 columns "
                             "(delta6 log or delta6 simulate output); without --replay, "
                             "--static, --twin or --live: a 20 s demo motion, looping")
    motion.add_argument("--static", action="store_true",
                        help="encoders at rest (zero deflection) unless the live channel moves "
                             "them")
    motion.add_argument("--twin", metavar="SCENARIO",
                        help="the digital twin drives the encoders live: a simulated run of "
                             "SCENARIO (ideal, paper, or one effect's name; delta6 simulate "
                             "--list), fed through the live channel at the board's pace")
    parser.add_argument("--seed", type=number("--seed", int, 0), default=0, metavar="N",
                        help="the twin's random seed (default 0)")
    parser.add_argument("--twin-duration", type=number("--twin-duration", low=1), default=120.0,
                        metavar="S", help="seconds of twin run, looped (default 120)")
    parser.add_argument("--loop", action="store_true", help="start the replay over at its end")
    parser.add_argument("--live", metavar="SOCKET", type=Path,
                        help="listen for live angle updates, faults and queries on this Unix "
                             "socket (protocol in docs/virtual-board.md)")
    parser.add_argument("--fault", action="append", default=[], metavar="E:KIND:T0:T1",
                        help="encoder E (1..6) fails with KIND (biterror, weak, strong, "
                             "noanswer) from T0 to T1 s of board time (T1 may be inf); "
                             "repeatable")
    parser.add_argument("--zero", metavar="C1,...,C6",
                        help="counts the emulated encoders report at zero deflection "
                             "(default 0, the firmware's uncalibrated zero)")
    parser.add_argument("--eeprom", metavar="FILE", type=Path,
                        help="the board's EEPROM image: loaded if it exists, saved at the end "
                             "(so a saved configuration survives restarts)")
    parser.add_argument("--stats", metavar="FILE", type=Path,
                        help="write the timing statistics (JSON) there at the end")
    parser.add_argument("--speed", type=number("--speed", low=0), default=1.0, metavar="X",
                        help="board time per wall time: 1 real time (default), 0 as fast as "
                             "the emulator runs")
    parser.add_argument("--duration", type=number("--duration", low=0, low_open=True),
                        metavar="S", help="stop after S seconds of board time (its time "
                                          "starts when a client opens the port)")
    from delta6.commands.codegen import add_allow_implausible
    add_allow_implausible(parser)


def parse_zero(text: str | None):
    if text is None:
        return 0
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise UserError(f"--zero takes six counts separated by commas, got {text!r}") from None
    if not valid_counts(values):
        raise UserError(f"--zero takes six counts 0..16383, got {text!r}")
    return values


def run(args: argparse.Namespace) -> int:
    # Checked now: the board saves both only when it ends, maybe hours later.
    if args.eeprom is not None:
        check_output_file(args.eeprom, "--eeprom", inputs=[args.replay, args.design,
                                                            args.calibration, args.model])
        if args.eeprom.exists() and not os.access(args.eeprom, os.R_OK):
            raise UserError(f"--eeprom {args.eeprom}: cannot be read (permission denied)")
    if args.stats is not None:
        check_output_file(args.stats, "--stats", inputs=[args.replay, args.design,
                                                          args.calibration, args.model,
                                                          args.eeprom])
        if args.eeprom is not None and args.stats.resolve() == args.eeprom.resolve():
            raise UserError(f"--stats {args.stats}: is the --eeprom image too (the statistics "
                            "would replace it)")
    faults = [vb.Fault.parse(spec) for spec in args.fault]
    zero = parse_zero(args.zero)
    if args.loop and args.replay is None:
        raise UserError("--loop goes with --replay")
    # The firmware first: its design checks refuse a unit slip before the twin simulates it.
    if args.design is not None or args.calibration is not None or args.model is not None:
        from delta6.commands.codegen import design_firmware
        image = design_firmware(args.design or Path(DEFAULT_DESIGN), args.calibration,
                                args.model, allow_implausible=args.allow_implausible)
    else:
        image = vb.firmware()
    run_of_twin = _simulate_twin(args) if args.twin else None
    replay_design = None
    if args.replay is not None:     # its log must come from the design the firmware is for
        from delta6.core.workspace import load_checked
        replay_design = load_checked(args.design or DEFAULT_DESIGN)
    with tempfile.TemporaryDirectory(prefix="delta6-virtual-") as tmp:
        replay, loop, what = args.replay, args.loop, None
        if replay is not None:
            what = f"replaying {replay}"
        elif run_of_twin is not None:
            what = (f"the digital twin, scenario {args.twin} (seed {args.seed}, "
                    f"{args.twin_duration:g} s looped), through the live channel")
        elif not args.static and args.live is None:
            from delta6.core.design import load
            limit = load(args.design or DEFAULT_DESIGN).joint_limit_rad
            t, theta = vb.demo_trajectory(limit_rad=limit)     # inside the design's joint box
            replay = vb.write_replay(Path(tmp) / "demo.d6rp", t, theta_to_counts(theta, zero))
            loop, what = True, "a demo motion (20 s, looping; --static for rest)"
        live = args.live if args.live is not None else run_of_twin is not None
        board = vb.VirtualBoard(image=image, replay=replay, loop=loop, zero=zero, live=live,
                                faults=faults, eeprom=args.eeprom, speed=args.speed,
                                duration=args.duration,
                                replay_design=replay_design)
        return _serve(board, args, what, run_of_twin)


def _simulate_twin(args: argparse.Namespace):
    from delta6 import twin
    from delta6.core.workspace import load_checked
    try:
        effects = twin.scenario_effects(args.twin, args.seed)
    except twin.EffectError as exc:
        raise UserError(str(exc)) from None
    design = load_checked(args.design or DEFAULT_DESIGN)
    print(f"simulating {args.twin_duration:g} s of the twin (scenario {args.twin}) ...",
          file=sys.stderr, flush=True)
    try:
        return twin.simulate(design, effects, args.twin_duration, TWIN_RATE_HZ, args.seed,
                             scenario=args.twin)
    except ValueError as exc:    # a design or setting the twin cannot run: one line
        raise UserError(f"--twin {args.twin}: the twin cannot simulate design "
                        f"'{design.name}': {exc}") from None


def _drive(board: vb.VirtualBoard, run_of_twin, speed: float, stop: threading.Event) -> None:
    """Feed the twin's angles through the live channel, paced by the board's clock."""
    from delta6.twin import iter_realtime
    samples = iter_realtime(run_of_twin, speed=speed if speed > 0 else 1e6, loop=True)
    try:
        board.live.drive(samples, stop=stop)
    except UserError:
        pass   # the board went away: the main thread reports how it ended


def _serve(board: vb.VirtualBoard, args: argparse.Namespace, what: str | None,
           run_of_twin=None) -> int:
    stop = threading.Event()          # ends the feeding thread; set by this thread only
    # The handler only notes the signal: setting the event from it could deadlock, as this
    # thread may hold the event's lock (inside its wait) when the signal arrives.
    requested: list[int] = []
    previous = {s: signal.signal(s, lambda signum, _frame: requested.append(signum))
                for s in STOP_SIGNALS}
    try:
        board.start()
        if run_of_twin is not None:
            threading.Thread(target=_drive, args=(board, run_of_twin, args.speed, stop),
                             daemon=True).start()
        print(board.port, flush=True)
        notes = [f"virtual board on {board.port}: firmware {board.image.elf.name} on an emulated "
                 f"ATmega328P at {NANO.f_cpu / 1e6:g} MHz, {board.baud} baud"]
        if what:
            notes.append(f"encoders: {what}")
        if board.live_path is not None:
            notes.append(f"live channel: {board.live_path}")
        notes.append("it starts when a client opens the port; Ctrl-C ends it")
        print("\n".join(notes), file=sys.stderr, flush=True)
        while not requested and board.running:
            time.sleep(0.2)
        stop.set()
        status = board.stop()
    finally:
        stop.set()
        for s, handler in previous.items():
            signal.signal(s, handler)
        if board.running:
            board.stop()
    if status not in (0, None):
        reason = board._error_text() or f"exit status {status}"
        board.close()
        raise UserError(f"the virtual board failed: {reason}")
    try:
        stats = board.stats()
    except UserError:
        stats = None
    if stats is not None:
        print(summary(stats), file=sys.stderr)
        if args.stats is not None:
            try:
                args.stats.write_text(json.dumps(stats, indent=2) + "\n")
            except OSError as exc:
                board.close()
                raise UserError(f"cannot write --stats {args.stats}: {exc.strerror}") from None
    board.close()
    return 0


def summary(stats: dict) -> str:
    t = stats["timing"]
    f = t["frequency"]
    enc = stats["encoders"]
    text = (f"ran {stats['board_seconds']:.1f} s of board time in {stats['wall_seconds']:.1f} s: "
            f"{t['samples']} samples, {t['missed_ticks']} missed periods, "
            f"CPU {t['cpu_busy']:.0%} busy, UART {t['uart_occupancy']:.0%} busy")
    if t["scan_cycles"]["n"]:
        text += (f"; scan {t['scan_cycles']['mean'] / f * 1e6:.0f} us, solve "
                 f"{t['solve_cycles']['mean'] / f * 1e6:.0f} us")
    if t["latency_cycles"]["n"]:
        text += (f", latch to last byte {t['latency_cycles']['mean'] / f * 1e3:.2f} ms mean, "
                 f"{t['latency_cycles']['max'] / f * 1e3:.2f} ms max")
    bad = sum(enc["violations"].values()) + enc["contention"]
    if bad:
        text += f"; encoder bus: {bad} timing violations or contention events"
    return text
