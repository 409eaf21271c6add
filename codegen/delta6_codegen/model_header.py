"""Render generated/delta6_model.h: an on-chip residual model (delta6.core.residualmodel) as
flash tables for the engine of firmware/lib/delta6_core/src/delta6_residual.h.

The header exists only when a model is compiled in (``delta6 codegen DESIGN --model MODEL``);
the application includes it with ``__has_include``, so without it the firmware is exactly the
one without a model. The text is a pure function of the model file and the labels.
"""
from __future__ import annotations

import numpy as np

from delta6.core.int8net import FEATURE_KINDS, MAX_STRIDE, MAX_WIDTH
from delta6.core.residualmodel import ResidualModel

from .design_header import GENERATED_MARKER, c_float, c_string

COMMAND = "delta6 codegen"
#: Must equal delta6::residual::kModelFormatVersion (the header static_asserts it).
MODEL_FORMAT_VERSION = 1
_PER_LINE = 16


def _int_table(ctype: str, name: str, values, comment: str) -> list[str]:
    values = [int(v) for v in np.asarray(values).reshape(-1)]
    suffix = "L" if ctype == "int32_t" else ""
    lines = [f"// {comment}", f"const {ctype} {name}[{len(values)}] DELTA6_FLASH = {{"]
    for i in range(0, len(values), _PER_LINE):
        lines.append("    " + ", ".join(f"{v}{suffix}" for v in values[i:i + _PER_LINE]) + ",")
    lines.append("};")
    return lines


def render_model(model: ResidualModel, design_label: str, model_label: str,
                 command: str | None = None) -> str:
    """The header text; ``command`` is the command line that wrote it (default: ``delta6
    codegen DESIGN --model MODEL``)."""
    net = model.net
    ns = "delta6::residual::"
    cal = (f"0x{model.calibration_hash:08X}UL" if model.calibration_hash is not None else "0UL")
    command = command or f"{COMMAND} {design_label} --model {model_label}"
    lines = [
        GENERATED_MARKER,
        f"// Written by `{command}` from the model file",
        f"// {model_label}. Without --model the file is removed and the firmware has no residual.",
        "#ifndef DELTA6_GENERATED_MODEL_H",
        "#define DELTA6_GENERATED_MODEL_H",
        "",
        "#include <stdint.h>",
        "",
        '#include "delta6_fastmath.h"',
        '#include "delta6_residual.h"',
        "",
        "namespace delta6 {",
        "namespace model {",
        "",
        f"constexpr char kName[] = {c_string(model.name)};",
        "// delta6.core.residualmodel.ResidualModel.hash32(): which model a board runs.",
        f"constexpr uint32_t kHash = 0x{model.hash32():08X}UL;",
        f"constexpr uint32_t kDesignHash = 0x{model.design_hash:08X}UL;   // trained for this design",
        f"constexpr uint32_t kCalibrationHash = {cal};   // over this calibration (0: analytical)",
        f"// {net.macs} multiply-accumulates per sample; trained at {net.rate_hz:g} Hz.",
        "",
    ]
    for i, layer in enumerate(net.layers):
        out, inp = layer.shape
        lines += _int_table("int8_t", f"kWeights{i}", layer.weights,
                            f"layer {i + 1}: {out} x {inp} weights, row-major")
        lines += _int_table("int32_t", f"kBias{i}", layer.bias, f"layer {i + 1}: bias")
        lines += _int_table("int16_t", f"kMultiplier{i}", layer.multiplier,
                            f"layer {i + 1}: Q15 requantization multipliers")
        lines += _int_table("uint8_t", f"kShift{i}", layer.shift, f"layer {i + 1}: shifts")
    lines += [f"const {ns}Layer kLayers[{len(net.layers)}] DELTA6_FLASH = {{"]
    for i, layer in enumerate(net.layers):
        out, inp = layer.shape
        lines.append(f"    {{{inp}, {out}, {int(layer.relu)}, kWeights{i}, kBias{i}, "
                     f"kMultiplier{i}, kShift{i}}},")
    lines += ["};", "// Feature groups: kind, param, requantization multipliers and shifts.",
              f"const {ns}Feature kFeatures[{len(net.features)}] DELTA6_FLASH = {{"]
    for f in net.features:
        mult = ", ".join(str(int(m)) for m in f.multiplier)
        shift = ", ".join(str(int(s)) for s in f.shift)
        lines.append(f"    {{{FEATURE_KINDS[f.kind]}, {int(f.param)}, {{{mult}}}, {{{shift}}}}},"
                     f"  // {f.kind}")
    lines += [
        "};",
        "const float kInputScale[6] DELTA6_FLASH = {"
        + ", ".join(c_float(float(v)) for v in net.input_scale) + "};",
        "const float kOutputStep[6] DELTA6_FLASH = {"
        + ", ".join(c_float(float(v)) for v in net.output_step) + "};",
        "",
        f"constexpr uint8_t kHistoryLength = {net.history_length()};",
        f"constexpr uint8_t kPlayCount = {len(net.play_radii())};",
        f"constexpr uint8_t kWrenchHistory = {int(net.max_lag('wrench_step') > 0)};",
        f"constexpr uint8_t kCountHistory = {int(net.max_lag('count_step') > 0)};",
        "// 0: no feature reads the base wrench (the application skips its float quantization).",
        "constexpr uint8_t kUsesWrench = "
        f"{int(any(f.kind in ('wrench', 'wrench_step') for f in net.features))};",
        f"const {ns}Model kModel = {{",
        f"    {int(round(net.rate_hz))}, {len(net.features)}, kFeatures, {len(net.layers)}, kLayers,"
        " kInputScale, kOutputStep,",
        "    kHistoryLength, kWrenchHistory, kCountHistory, kPlayCount,",
        "};",
        "",
        "}  // namespace model",
        "}  // namespace delta6",
        "",
        f"static_assert(delta6::residual::kModelFormatVersion == {MODEL_FORMAT_VERSION},",
        f'              "delta6_model.h is older than the residual engine: rerun {COMMAND}");',
        # The Python engine's limits, which the model was checked against, are the board's.
        f"static_assert(delta6::residual::kMaxWidth == {MAX_WIDTH} && "
        f"delta6::residual::kMaxStride == {MAX_STRIDE},",
        '              "the residual engine\'s limits differ from delta6.core.int8net\'s");',
        "",
        "#endif  // DELTA6_GENERATED_MODEL_H",
        "",
    ]
    return "\n".join(lines)
