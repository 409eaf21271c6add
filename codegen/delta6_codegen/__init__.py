"""Code generation for the Delta6 firmware: the per-design C++ header.

``render(design, label)`` gives the text of generated/delta6_design.h;
``solver_constants(design)`` the numbers in it (also used by the native tests);
``render_calibration(design, calibration, ...)`` gives generated/delta6_calibration.h and
``calibration_constants`` its numbers.
"""
from .calibration_header import CalibrationConstants, calibration_constants
from .calibration_header import render as render_calibration
from .design_header import render
from .solver_constants import SolverConstants, solver_constants

__all__ = ["render", "solver_constants", "SolverConstants", "render_calibration",
           "calibration_constants", "CalibrationConstants"]
