#!/usr/bin/env python3
"""Whether two ``delta6 diagnose --json`` results of the same log give the same verdict.

    .venv/bin/python tools/diagnosis_verdict_check.py before.json after.json [--rtol 1e-6]

Every name, order, flag and text must be equal (present, partial, minor and group verdicts,
the ladder and its order, the candidates, the leftover's verdict, ...) and every number equal
to ``--rtol`` (relative, with an absolute floor of ``--atol``): the shares, gains, p99s and
parameters. Only the run time (``seconds``) is left out. Prints each difference with its
path in the JSON; exit status 1 when there is one, 0 when there is none. Used to show that a
change to how the diagnosis computes (memory, speed) leaves its results alone.
"""
from __future__ import annotations

import argparse
import json
import math
import sys

IGNORED = {"seconds"}


def differences(a, b, rtol: float, atol: float, path: str = "$"):
    """Paths (with both values) where ``a`` and ``b`` differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b)):
            if key in IGNORED:
                continue
            if key not in a or key not in b:
                yield f"{path}.{key}: only in {'after' if key not in a else 'before'}"
                continue
            yield from differences(a[key], b[key], rtol, atol, f"{path}.{key}")
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{path}: {len(a)} items before, {len(b)} after"
            return
        for i, (x, y) in enumerate(zip(a, b)):
            yield from differences(x, y, rtol, atol, f"{path}[{i}]")
    elif (isinstance(a, (int, float)) and isinstance(b, (int, float))
          and not isinstance(a, bool) and not isinstance(b, bool)):
        if not math.isclose(a, b, rel_tol=rtol, abs_tol=atol):
            yield f"{path}: {a!r} before, {b!r} after"
    elif a != b:
        yield f"{path}: {a!r} before, {b!r} after"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before")
    parser.add_argument("after")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--atol", type=float, default=1e-12)
    args = parser.parse_args(argv)
    try:
        with open(args.before) as f:
            before = json.load(f)
        with open(args.after) as f:
            after = json.load(f)
    except (OSError, ValueError) as exc:
        print(f"cannot read a diagnosis: {exc}", file=sys.stderr)
        return 2
    found = list(differences(before, after, args.rtol, args.atol))
    for line in found:
        print(line)
    print(f"{len(found)} difference(s) beyond rtol {args.rtol:g}; present before "
          f"{before.get('present')}, after {after.get('present')}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
