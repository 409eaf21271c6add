"""Protocol benchmark: prints the figures of docs/protocol.md ("Performance").

    .venv/bin/python tools/bench_protocol.py            # about 30 s
    .venv/bin/python tools/bench_protocol.py --records 500000   # quicker

1. wire bytes per record and the highest sample rate per baud rate;
2. bulk decoding of a large capture made by the firmware's own protocol core (the simulated
   device): records per second (floor: 1,000,000);
3. the incremental decoder fed as a serial port delivers, CPU per record and the share of one
   core at 2,000 records/s (floor: under 5 %); and the whole host path (Device reader thread,
   queue, a consumer reading blocks) at 2,000 records/s in real time through a pty;
4. the AVR footprint of the protocol core (ATmega328P flash and static RAM), if avr-g++ exists;
5. its cycle costs on the ATmega328P, a scripted session run in the simavr emulator (the same
   session the tests compare byte for byte with the native build), if simavr exists.
"""
from __future__ import annotations

import argparse
import shutil
import sys
import threading
import time

from delta6.build import avrbuild, nativebuild
from delta6.link import protocol as P
from delta6.link.bulkdecode import decode_capture
from delta6.link.decoder import StreamDecoder
from delta6.link.device import Device
from delta6.sim.simdevice import SimulatedDevice

BAUDS = (115_200, 230_400, 250_000, 460_800, 500_000, 921_600, 1_000_000, 2_000_000)


def wire_table() -> None:
    print("1. Wire size and rate limits")
    for t in P.RecordType:
        print(f"   {t.name:<11} {P.RECORD_SIZES[t]:>4} payload bytes, {P.wire_bytes(t):>4} on the wire")
    print(f"   {'baud':>9}  {'wrench Hz':>10} {'(90 %)':>8}  {'wrench+raw Hz':>13} {'(90 %)':>8}")
    for baud in BAUDS:
        print(f"   {baud:>9}  {P.max_rate_for_link(baud, P.Mode.WRENCH):>10.0f} "
              f"{P.link_rate_limit(baud, P.Mode.WRENCH):>8}  "
              f"{P.max_rate_for_link(baud, P.Mode.WRENCH_RAW):>13.0f} "
              f"{P.link_rate_limit(baud, P.Mode.WRENCH_RAW):>8}")
    print("   (90 %: what the device accepts; the rest carries answers and telemetry)")


def make_capture(records: int) -> bytes:
    """A capture from the firmware core: 3/4 wrench, then 1/4 wrench+raw, 1 kHz."""
    sim = SimulatedDevice(rate_hz=1000, baud=1_000_000)
    sim.write(P.encode_command(P.Command.START, 1, 1000))
    chunks = []
    raw_from = records * 3 // 4
    seconds = records / 1000
    step = 10.0
    t = 0.0
    while t < seconds:
        if t <= raw_from / 1000 < t + step:
            sim.advance(raw_from / 1000 - t)
            sim.write(P.encode_command(P.Command.SET_MODE, 2, 2))
            t = raw_from / 1000
        span = min(step, seconds - t)
        sim.advance(span)
        t += span
        chunks.append(sim.read())
    sim.close()
    return b"".join(chunks)


def bulk(data: bytes) -> None:
    decode_capture(data[:100_000])                       # build the CRC tables
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        cap = decode_capture(data)
        best = min(best, time.perf_counter() - t0)
    n = len(cap) + len(cap.other)
    print(f"2. Bulk decode: {len(data) / 1e6:.1f} MB, {n} records ({len(cap)} data, "
          f"{int(cap.has_counts.sum())} with raw counts), errors {cap.stats.errors}")
    print(f"   {best:.3f} s -> {n / best:,.0f} records/s, {len(data) / best / 1e6:.0f} MB/s "
          f"(floor 1,000,000 records/s)")


def incremental(data: bytes) -> None:
    n_bytes = min(len(data), 2_000_000)
    part = data[:n_bytes]
    for chunk in (64, 512):
        decoder = StreamDecoder()
        t0 = time.process_time()
        records = 0
        for i in range(0, n_bytes, chunk):
            records += len(decoder.feed(part[i:i + chunk]))
        cpu = time.process_time() - t0
        per = cpu / records
        print(f"3. Incremental decoder, {chunk}-byte reads: {per * 1e6:.2f} us CPU per record; "
              f"at 2,000 records/s {100 * 2000 * per:.2f} % of one core (floor < 5 %)")


def host_path(seconds: float = 3.0, rate: int = 2000) -> None:
    """The whole host path in real time: a feeder writes frames into a pseudo-terminal at
    ``rate`` (the OS serial path a USB-CDC device uses), the Device's reader thread decodes and
    queues them, the main thread reads blocks as an application would."""
    import os
    import tty
    frames = [P.encode_wrench(i & 0xFFFF, (i * 500) & 0xFFFFFFFF, 0,
                              (i % 300, -5, 7, 100, -100, 3)) for i in range(rate * 4)]
    sim = SimulatedDevice()
    info_frame = sim.read().split(b"\x00")[2] + b"\x00"
    sim.close()
    per_ms = rate // 1000

    def feeder(master, stop):
        def feed():
            t_next = time.perf_counter()
            i = 0
            while not stop.is_set():
                os.write(master, b"".join(frames[i:i + per_ms]))
                i = (i + per_ms) % len(frames)
                t_next += 1e-3
                time.sleep(max(0.0, t_next - time.perf_counter()))
        return threading.Thread(target=feed, daemon=True)

    def run(consume) -> tuple[float, float]:
        master, slave = os.openpty()
        tty.setraw(slave)
        stop = threading.Event()
        try:
            state = consume(slave, master, stop)
            cpu0, wall0 = time.process_time(), time.perf_counter()
            thread = feeder(master, stop)
            thread.start()
            count = 0
            while time.perf_counter() - wall0 < seconds:
                count += state()
            cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
            stop.set()
            thread.join()
            return 100 * cpu / wall, count / wall
        finally:
            os.close(master)
            os.close(slave)

    def bare(slave, master, stop):
        return lambda: len(os.read(slave, 65536)) // P.wire_bytes(P.RecordType.WRENCH)

    base_cpu, _ = run(bare)
    box = {}

    def device(slave, master, stop):
        dev = Device(os.ttyname(slave), handshake=False).open()
        os.write(master, info_frame)
        box["dev"] = dev

        def step():
            n = len(dev.read_block(timeout=1.0))
            time.sleep(0.01)                  # an application reading 100 times a second
            return n
        return step

    dev_cpu, received = run(device)
    lost = box["dev"].health.samples_lost
    box["dev"].close()
    print(f"   Whole host path through a pty in real time: {received:,.0f} samples/s, {lost} "
          f"lost, {dev_cpu:.1f} % of one core; the feeder with a bare os.read loop alone takes "
          f"{base_cpu:.1f} %, so the library's share is {dev_cpu - base_cpu:.1f} %")


def footprint() -> None:
    if shutil.which("avr-g++") is None:
        print("4. AVR footprint: avr-g++ not installed (tools/bootstrap.sh installs it)")
        return
    program = [nativebuild.FIRMWARE_NATIVE / "avr_footprint.cpp", *nativebuild.core_sources()]
    includes = [nativebuild.FIRMWARE_CORE, avrbuild.COMMITTED_DESIGN_INCLUDE / "generated"]
    sizes = avrbuild.build_image("protocol_footprint", program, includes, arduino=False).sizes
    print(f"4. AVR footprint (ATmega328P, -Os -flto, float library included): flash "
          f"{sizes.flash} bytes, static RAM {sizes.ram} bytes (the Device object, a stub board)")


def avr_cycles() -> None:
    """Cycle costs on the emulated ATmega328P: the scripted session of
    firmware/native/avr_session.cpp (whose output the tests compare with the native build)."""
    if shutil.which("avr-g++") is None or shutil.which("simavr") is None:
        print("5. AVR cycles: avr-g++ or simavr not installed (tools/bootstrap.sh installs them)")
        return
    from delta6.sim import avrsession as avr_session
    result = avr_session.run_on_avr()
    same = result.uart == avr_session.run_natively()
    c = avr_session.cycles(result)

    def fig(name):
        return f"{c[name]:.0f} ({c[name] / (avrbuild.NANO.f_cpu / 1e6):.0f} us)"

    print(f"5. AVR cycles (ATmega328P at {avrbuild.NANO.f_cpu / 1e6:g} MHz, emulated; mean per call; output "
          f"{'identical to' if same else 'DIFFERENT FROM'} the native build):")
    print(f"   onSample: stopped {fig('stopped')}, streaming wrench {fig('wrench')}, "
          f"wrench+raw {fig('raw')}, wrench+raw tared {fig('raw_tared')}")
    print(f"   the byte completing a command: start {fig('start')}, get_info {fig('get_info')} "
          f"(a {P.RECORD_SIZES[P.RecordType.INFO]}-byte record), "
          f"get_telemetry {fig('get_telemetry')}; begin {fig('begin')}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--records", type=int, default=2_000_000,
                        help="data records in the capture (default 2,000,000)")
    args = parser.parse_args()
    wire_table()
    t0 = time.perf_counter()
    data = make_capture(args.records)
    print(f"   (capture of {args.records:,} samples made by the firmware core in "
          f"{time.perf_counter() - t0:.1f} s)")
    bulk(data)
    incremental(data)
    host_path()
    footprint()
    avr_cycles()
    return 0


if __name__ == "__main__":
    sys.exit(main())
