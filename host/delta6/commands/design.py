"""``delta6 design``: the specification of one or more design variants (Tables II and III)."""
from __future__ import annotations

import argparse
import json
import sys

from delta6.core import design as design_mod
from delta6.core.paths import DEFAULT_DESIGN
from delta6.core.spec import Spec, converged_spec, grid_spec
from delta6.core.workspace import load_checked

NAME = "design"
HELP = "print the specification of design variants (workspace, ranges, resolution)"
MAX_GRID = 32


def _grid(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--grid takes a whole number, got {text!r}") from None
    if not 2 <= n <= MAX_GRID:
        raise argparse.ArgumentTypeError(f"--grid must be between 2 and {MAX_GRID}, got {n}")
    return n


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("designs", nargs="*", metavar="DESIGN.toml",
                        help="design file(s); the paper's Delta6 (designs/delta6.toml) when none is given")
    parser.add_argument("--grid", type=_grid, metavar="N",
                        help="sample N angles per joint as the paper did (10 reproduces its "
                             "tables); default: the converged limits over the joint box")
    parser.add_argument("--json", action="store_true",
                        help="print JSON (one object, or a list for several designs)")


def evaluate(path: str, grid: int | None) -> tuple[design_mod.Design, Spec]:
    d = load_checked(path)
    return d, (grid_spec(d, grid) if grid else converged_spec(d))


def run(args: argparse.Namespace) -> int:
    results = [(path, *evaluate(path, args.grid)) for path in (args.designs or [str(DEFAULT_DESIGN)])]
    for _, d, _ in results:
        for note in design_mod.unit_slip_notes(d):
            print(note, file=sys.stderr)
    if args.json:
        objects = [{"design": d.name, "file": path, "hash": f"0x{d.hash32():08x}", **s.as_dict()}
                   for path, d, s in results]
        print(json.dumps(objects[0] if len(objects) == 1 else objects, indent=2))
    elif len(results) == 1:
        print(format_single(*results[0]))
    else:
        print(format_table(results))
    return 0


def _g(value: float, digits: int = 4) -> str:
    """``digits`` significant digits, trailing zeros kept (25.10, not 25.1)."""
    text = f"{value:#.{digits}g}"
    return text.rstrip(".") if "e" not in text else text


def _method_suffix(method: str) -> str:
    return " points per joint" if method.startswith("grid") else " limits over the joint box"


def format_single(path: str, d: design_mod.Design, s: Spec) -> str:
    ks = sorted(set(d.k_nm_per_rad))
    k_text = f"{ks[0]:g}" if len(ks) == 1 else "[" + ", ".join(f"{k:g}" for k in d.k_nm_per_rad) + "]"
    fr, mr = s.force_range_n, s.torque_range_nm
    lines = [
        f"Design '{d.name}' ({path}), hash 0x{d.hash32():08x}",
        f"  a = {d.a_mm:g} mm, b = {d.b_mm:g} mm, c = {d.c_mm:g} mm, "
        f"la = {d.la_mm:g} mm, lb = {d.lb_mm:g} mm",
        f"  theta_offset = {d.theta_offset_rad:.4f} rad, k = {k_text} N*m/rad, "
        f"joint box |theta_e| <= {d.joint_limit_rad:.4f} rad",
        f"Specification ({s.method}{_method_suffix(s.method)})",
        "  TCP workspace       " + " x ".join(_g(v) for v in s.workspace_mm) + " mm",
    ]
    for axis in "xyz":
        lo, hi = fr[axis]
        lines.append(f"  F{axis} range            {_g(lo)} .. {_g(hi)} N")
    for axis in "xyz":
        lo, hi = mr[axis]
        lines.append(f"  M{axis} range            {_g(lo)} .. {_g(hi)} N*m")
    fs = s.full_scale
    lines += [
        f"  |F| max             {_g(s.force_norm_max_n)} N",
        f"  |M| max             {_g(s.torque_norm_max_nm)} N*m",
        f"  force resolution    {_g(s.force_resolution_n)} N    (worst case, one encoder count)",
        f"  torque resolution   {_g(s.torque_resolution_nm)} N*m",
        "  full scale          " + ", ".join(f"{a} {_g(v)}" for a, v in
                                              zip(("Fx", "Fy", "Fz"), fs[:3])) + " N; "
        + ", ".join(f"{a} {_g(v)}" for a, v in zip(("Mx", "My", "Mz"), fs[3:])) + " N*m",
    ]
    return "\n".join(lines)


def _k_range(d: design_mod.Design) -> str:
    """The spring rate for a table cell: one value, or the per-joint list's min..max."""
    lo, hi = min(d.k_nm_per_rad), max(d.k_nm_per_rad)
    return f"{lo:.6g}" if lo == hi else f"{lo:.4g}..{hi:.4g}"


def format_table(results) -> str:
    header = (f"{'design':<20} {'a mm':>6} {'b mm':>6} {'la mm':>6} {'lb mm':>6} {'th_off':>6} "
              f"{'lim rad':>7} {'k Nm/rad':>13} {'|Fmax| N':>9} {'|Mmax| Nm':>9} {'Fres N':>8} "
              f"{'Mres Nm':>8}")
    lines = [header, "-" * len(header)]
    for _path, d, s in results:
        lines.append(f"{d.name:<20} {d.a_mm:>6.4g} {d.b_mm:>6.4g} {d.la_mm:>6.4g} {d.lb_mm:>6.4g} "
                     f"{d.theta_offset_rad:>6.3f} {d.joint_limit_rad:>7.4f} {_k_range(d):>13} "
                     f"{_g(s.force_norm_max_n):>9} {_g(s.torque_norm_max_nm):>9} "
                     f"{_g(s.force_resolution_n):>8} {_g(s.torque_resolution_nm, 3):>8}")
    lines.append(f"({results[0][2].method}; lim: the joint box |theta_e| <= lim; Fres, Mres: "
                 "worst case for one encoder count)")
    return "\n".join(lines)
