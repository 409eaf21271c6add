"""Code generation for the Delta6 firmware: the per-design C++ header.

``render(design, label)`` gives the text of generated/delta6_design.h;
``solver_constants(design)`` the numbers in it (also used by the native tests).
"""
from .design_header import render
from .solver_constants import SolverConstants, solver_constants

__all__ = ["render", "solver_constants", "SolverConstants"]
