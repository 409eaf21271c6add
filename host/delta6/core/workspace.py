"""Whether a design's kinematics is well defined over its whole joint box.

Two things can go wrong with a geometry: the three link spheres do not meet for some joint
angles (no forward-kinematics solution, the sqrt of eq. trilateration turns negative), or the
mechanism passes through a singular pose where the eq. (7) lever vanishes and forces become
unbounded. Both are checked at their exact worst case over the box, not only on a grid.
"""
from __future__ import annotations

import numpy as np

from delta6.core import boxsearch
from delta6.core.design import Design, DesignError, load
from delta6.core.model import Params, branch_forces, forward_kinematics

#: The trilateration height must stay above this fraction of lb: a margin against rounding
#: (the float32 firmware takes a square root of it).
MIN_HEIGHT_FRACTION = 0.05
#: The eq. (7) lever must stay above this fraction of la everywhere in the box.
MIN_LEVER_FRACTION = 0.05


def joint_box(design: Design, joints: int = 6) -> tuple[np.ndarray, np.ndarray]:
    return design.joint_box(joints)


def load_checked(path) -> Design:
    """Load a design file and prove its kinematics solvable over the whole joint box: what every
    command that computes with a design uses (one-line :class:`DesignError` otherwise)."""
    design = load(path)
    check_solvable(design, str(path))
    return design


def check_solvable(design: Design, source: str | None = None) -> None:
    """Raise :class:`DesignError` unless the kinematics is solvable and non-singular everywhere
    in the joint box of joints 1..3."""
    p = Params.from_design(design)
    lo, hi = joint_box(design, 3)

    def height2(t):
        return forward_kinematics(p, t, return_disc=True)[1]

    rest = np.zeros(3)
    worst, where = boxsearch.minimize(height2, lo, hi, seeds=7, starts=4, passes=16)
    least = (MIN_HEIGHT_FRACTION * design.lb_mm * 1e-3) ** 2
    if not worst > least:
        raise DesignError("lb_mm", "forward kinematics has no solution in the joint box "
                          f"(links cannot close at theta_e1..3 = {_fmt(where)} rad)"
                          + _box_fix(height2(rest) > least), source)

    def lever(t):
        _, lev = branch_forces(p, t)
        return np.abs(lev).min(axis=-1)

    worst, where = boxsearch.minimize(lever, lo, hi, seeds=7, starts=4, passes=16)
    least = MIN_LEVER_FRACTION * design.la_mm * 1e-3
    if not worst > least:
        raise DesignError("la_mm", "the mechanism is singular in the joint box (link force "
                          f"unbounded at theta_e1..3 = {_fmt(where)} rad)"
                          + _box_fix(lever(rest) > least), source)


def _box_fix(fine_at_rest: bool) -> str:
    """When the rest pose is fine, the joint box reaches the bad pose: a smaller box (or
    another rest angle) is a fix too, not only other lengths."""
    if not fine_at_rest:
        return ""
    return ("; or reduce joint_limit_rad / change theta_offset_rad (the rest pose is fine: "
            "the joint box reaches the bad pose)")


def _fmt(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:+.3f}" for v in values) + "]"
