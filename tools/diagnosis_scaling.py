#!/usr/bin/env python3
"""Time and peak memory of ``delta6 diagnose`` against the log's length.

    .venv/bin/python tools/diagnosis_scaling.py                       # 1e5, 4e5, 2e6 samples
    .venv/bin/python tools/diagnosis_scaling.py --samples 1e5 4e5     # some lengths only
    .venv/bin/python tools/diagnosis_scaling.py --samples 2e6 --effect harness:formulation=cable
    .venv/bin/python tools/diagnosis_scaling.py --samples 4e5 --json out/   # keep each JSON

Each log is a scenario of the digital twin (50 Hz; `paper` unless ``--scenario`` names another,
with the effects of ``--effect`` added, as ``delta6 sim --effect`` takes them): one run of up to
2 x 10^5 samples,
repeated end to end (time keeps increasing) up to the length asked for, so that long logs cost
minutes to make, not hours. Each diagnosis runs as its own ``delta6 diagnose`` process; its
wall time, CPU time and peak resident memory (getrusage of the child itself) are printed as a
Markdown table. On a shared machine the CPU time is the figure to compare: the wall time also
counts what other processes took. With ``--json DIR`` each diagnosis is also written to
``DIR/diagnosis-<samples>.json`` (``tools/diagnosis_verdict_check.py`` compares two).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from delta6 import twin

ROOT = Path(__file__).resolve().parents[1]
BASE_SAMPLES = 200_000
#: The diagnosis in a child process that reports its own peak resident memory (kB).
_CHILD = ("import resource, sys; from delta6.cli import main; "
          "code = main(['diagnose', sys.argv[1], '--quiet'] + sys.argv[2:]); "
          "u = resource.getrusage(resource.RUSAGE_SELF); "
          "print('usage', u.ru_utime + u.ru_stime, u.ru_maxrss, file=sys.stderr); "
          "sys.exit(code)")


def make_log(path: Path, samples: int, seed: int, scenario: str = "paper",
             effects: tuple[str, ...] = ()) -> None:
    from delta6.core.design import load
    from delta6.core.paths import DEFAULT_DESIGN
    from delta6.link.logfile import LogWriter

    design = load(DEFAULT_DESIGN)
    base = min(samples, BASE_SAMPLES)
    requests = twin.SCENARIOS[scenario] + tuple(twin.parse_request(e) for e in effects)
    run = twin.simulate(design, twin.build_effects(requests, seed), duration_s=base / 50,
                        seed=seed, record_temp=True, oversample=2)
    span = run.t[-1] - run.t[0] + (run.t[1] - run.t[0])
    with LogWriter(path, {"design": design.name, "source": "tools/diagnosis_scaling.py"},
                   optional=("temp_c",)) as log:
        done, k = 0, 0
        while done < samples:
            n = min(base, samples - done)
            log.write_block(run.t[:n] + k * span, run.theta[:n], run.wrench[:n],
                            temp_c=run.temp_c[:n])
            done += n
            k += 1


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", nargs="+", type=float, default=[1e5, 4e5, 2e6])
    parser.add_argument("--seed", type=int, default=5)
    parser.add_argument("--scenario", default="paper", choices=sorted(twin.SCENARIOS),
                        help="the twin's scenario (default: paper)")
    parser.add_argument("--effect", action="append", default=[], metavar="NAME[:k=v,...]",
                        help="an effect added to the scenario (repeatable)")
    parser.add_argument("--json", metavar="DIR", help="also write each diagnosis here")
    args = parser.parse_args()
    try:
        for e in args.effect:
            twin.parse_request(e)
    except twin.EffectError as exc:
        parser.error(str(exc))
    rows = []
    with tempfile.TemporaryDirectory(prefix="delta6-scaling-") as work:
        for n in (int(s) for s in args.samples):
            path = Path(work) / f"log-{n}.csv"
            make_log(path, n, args.seed, args.scenario, tuple(args.effect))
            extra = [] if args.json is None else [
                "--json", str(Path(args.json) / f"diagnosis-{n}.json")]
            started = time.perf_counter()
            proc = subprocess.run([sys.executable, "-c", _CHILD, str(path), *extra],
                                  capture_output=True, text=True)
            seconds = time.perf_counter() - started
            if proc.returncode != 0:
                print(proc.stderr, file=sys.stderr)
                return 1
            _, cpu, peak_kb = proc.stderr.strip().splitlines()[-1].split()
            rows.append((n, seconds, float(cpu), int(peak_kb) / 1024.0))
            print(f"{n:>9} samples: {seconds:7.1f} s wall, {float(cpu):7.1f} s CPU, peak "
                  f"{rows[-1][3]:7.0f} MiB", flush=True)
            path.unlink()
    print("\n| samples | wall time, s | CPU time, s | peak memory, MiB |\n|---|---|---|---|")
    for n, seconds, cpu, mb in rows:
        print(f"| {n:.0e} | {seconds:.0f} | {cpu:.0f} | {mb:.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
