"""Render firmware/include/generated/delta6_design.h for one design.

The output is a pure function of the design (and of the label naming its file): floats are
rounded to float32 once and printed with 9 significant digits (enough to round-trip every
float32), so the same design always gives the same bytes on every machine.
"""
from __future__ import annotations

import numpy as np

from delta6.core.design import Design
from delta6.core.spec import full_scale

from .solver_constants import CONSTANTS_VERSION, TABLE_STEP, SolverConstants, f32, solver_constants

COMMAND = "delta6 codegen"
#: The first line of every header delta6 codegen writes: what it may replace or remove (a
#: header without it is someone's own, never touched).
GENERATED_MARKER = "// GENERATED FILE - DO NOT EDIT."
LINE_LIMIT = 100


def c_float(x: float) -> str:
    """A C float literal for the float32 nearest ``x`` (round-trips exactly)."""
    text = f"{f32(x):.9g}"
    if not any(ch in text for ch in ".en"):
        text += ".0"
    return text + "f"


def c_string(text: str) -> str:
    # Names are validated printable ASCII; escape what a C string literal cannot hold as is,
    # and every '?' so that no "??/" (a trigraph: a backslash before C++17) forms.
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("?", "\\?") + '"'


def _float_list(values) -> str:
    return "{" + ", ".join(c_float(v) for v in values) + "}"


def _array(decl: str, values, comment: str) -> list[str]:
    """``decl = {...};  // comment``, broken after the brace when the line would be long."""
    line = f"{decl} = {_float_list(values)};  // {comment}"
    if len(line) <= LINE_LIMIT:
        return [line]
    return [f"// {comment}", f"{decl} = {{", "    " + ", ".join(c_float(v) for v in values),
            "};"]


def _six_on_two_lines(values) -> list[str]:
    """A 6-float brace list as a struct member, three values per line."""
    first, second = (", ".join(c_float(v) for v in part) for part in (values[:3], values[3:]))
    return [f"    {{{first},", f"     {second}}},"]


def _table(name: str, rows: np.ndarray, comment: str) -> list[str]:
    """A flash table, one row (triple) per line."""
    rows = np.asarray(rows, dtype=np.float32)
    lines = [f"// {comment}", f"const float {name}[{rows.size}] DELTA6_FLASH = {{"]
    lines += ["    " + ", ".join(c_float(float(v)) for v in row) + "," for row in rows]
    lines.append("};")
    return lines


def render(design: Design, source_label: str, constants: SolverConstants | None = None,
           command: str | None = None) -> str:
    """The header text for ``design``; ``source_label`` names the design file in the banner and
    ``command`` the command line that wrote it (default: ``delta6 codegen LABEL``)."""
    c = constants or solver_constants(design)
    fs = full_scale(design)
    mm = 1e-3
    command = command or f"{COMMAND} {source_label}"
    if command == f"{COMMAND} {source_label}" and source_label.startswith("designs/"):
        # A shipped design's header at its committed place: the test holds it to its design.
        regenerate = ["// Regenerate with that command; tests/firmware/test_codegen.py fails "
                      "when this file is out of",
                      "// date. Values are SI units rounded to float32 (codegen/delta6_codegen/)."]
    else:
        regenerate = ["// Regenerate with that command. Values are SI units rounded to float32",
                      "// (codegen/delta6_codegen/)."]
    lines = [
        GENERATED_MARKER,
        f"// Written by `{command}` from the design file {source_label}.",
        *regenerate,
        "#ifndef DELTA6_GENERATED_DESIGN_H",
        "#define DELTA6_GENERATED_DESIGN_H",
        "",
        "#include <stdint.h>",
        "",
        '#include "delta6_fastmath.h"',
        '#include "delta6_solver.h"',
        "",
        "namespace delta6 {",
        "namespace design {",
        "",
        f"constexpr char kName[] = {c_string(design.name)};",
        "// delta6.core.design.Design.hash32(): which variant a board runs.",
        f"constexpr uint32_t kHash = 0x{design.hash32():08X}UL;",
        "",
        "// Design parameters.",
        f"constexpr float kA = {c_float(design.a_mm * mm)};  // m",
        f"constexpr float kB = {c_float(design.b_mm * mm)};  // m",
        f"constexpr float kC = {c_float(design.c_mm * mm)};  // m",
        f"constexpr float kLa = {c_float(design.la_mm * mm)};  // m",
        f"constexpr float kLb = {c_float(design.lb_mm * mm)};  // m",
        f"constexpr float kThetaOffset = {c_float(design.theta_offset_rad)};  // rad",
        *_array("constexpr float kSpringRate[6]", design.k_nm_per_rad, "N*m/rad, joints 1..6"),
        "// Joint box: |theta_e| <= kJointLimitRad, i.e. |count delta| <= kJointLimitCounts.",
        f"constexpr float kJointLimitRad = {c_float(c.limit_rad)};",
        f"constexpr int16_t kJointLimitCounts = {c.limit_counts};",
        *_array("constexpr float kFullScale[6]", fs,
                "full scale of Fx, Fy, Fz (N), Mx, My, Mz (N*m): delta6.core.spec.full_scale"),
        "",
        "// Solver tables (fastmath::table_cos_sin): coarse rows every kTableStep counts from",
        "// q = -table_origin counts, fine rows for l = 0 .. kTableStep-1 counts.",
        *_table("kBranchTable", c.branch_table,
                "la cos(theta_offset + q), la sin(theta_offset + q), their sum"),
        *_table("kJointTable", c.joint_table, "cos q, sin q, cos q + sin q"),
        *_table("kFineTable", c.fine_table, "cos l, sin l - cos l, cos l + sin l"),
        "",
        "// Constants of delta6::solve_counts / solve_radians for this design.",
        "constexpr SolverConstants kSolverConstants = {",
        f"    {c_float(c.d)},  // d = a - b, m",
        f"    {c_float(c.la)},  // la, m",
        f"    {c_float(c.theta_offset)},  // theta_offset, rad",
        f"    {c_float(c.lb_sq)},  // lb^2, m^2",
        "    // spring_rate, N*m/rad; torque_per_count, N*m per encoder count",
        *_six_on_two_lines(c.spring_rate),
        *_six_on_two_lines(c.torque_per_count),
        f"    {c_float(c.limit_rad)},  // limit_rad",
        f"    {c.limit_counts},  // limit_counts",
        f"    {c.table_origin},  // table_origin",
        f"    {c_float(c.min_area)},  // min_area, m^2",
        f"    {c_float(c.min_height_sq)},  // min_height_sq, m^2",
        f"    {c_float(c.min_lever)},  // min_lever, m^2",
        "    kBranchTable,",
        "    kJointTable,",
        "    kFineTable,",
        "};",
        "",
        "}  // namespace design",
        "}  // namespace delta6",
        "",
        f"static_assert(delta6::kSolverConstantsVersion == {CONSTANTS_VERSION},",
        f'              "delta6_design.h is older than the solver: rerun {COMMAND}");',
        f"static_assert(delta6::kTableStep == {TABLE_STEP},",
        f'              "delta6_design.h was generated for another table step: rerun {COMMAND}");',
        "",
        "#endif  // DELTA6_GENERATED_DESIGN_H",
        "",
    ]
    return "\n".join(lines)
