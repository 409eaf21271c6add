"""Code generation for the Delta6 firmware: the per-design header and the wire layout header.

``render(design, label)`` gives the text of generated/delta6_design.h;
``solver_constants(design)`` the numbers in it (also used by the native tests);
``render_wire()`` the text of the core's generated/delta6_wire.h (the protocol's tables);
``render_calibration(design, calibration, ...)`` gives generated/delta6_calibration.h and
``calibration_constants`` its numbers;
``render_model(model, ...)`` the text of generated/delta6_model.h (an on-chip residual model);
every one starts with ``GENERATED_MARKER``.
"""
from .calibration_header import CalibrationConstants, calibration_constants
from .calibration_header import render as render_calibration
from .design_header import GENERATED_MARKER, render
from .model_header import render_model
from .solver_constants import SolverConstants, solver_constants
from .wire_header import render_wire

__all__ = ["GENERATED_MARKER", "render", "render_model", "render_wire", "solver_constants", "SolverConstants",
           "render_calibration", "calibration_constants", "CalibrationConstants"]
