"""A path that loads one axis at a time, like the paper's cross-axis test (Fig. 9): slow pushes
along a single wrench axis with long holds, the six axes one after the other.

The log is cut into six equal stretches, one per axis (Fx, Fy, Fz, Mx, My, Mz); inside its
stretch an axis is pushed alternately positive and negative: a minimum-jerk ramp from rest to
the push, a hold, a ramp back, a rest, drawn until they fill the stretch and then sped up
together to end with it (each push back at rest when the next axis begins: the path is
continuous). The joint deflections of a push are those that load
that axis alone at the rest pose (the inverse of the model's wrench Jacobian there), scaled to
a random share of the joint box; away from rest the wrench is not purely on one axis any more,
as with a real robot pushing in a straight line.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from delta6.core import model
from delta6.core.spec import full_scale
from delta6.twin.trajectory import quintic_moves


@dataclass(frozen=True)
class PushSettings:
    ramp_min_s: float = 4.0
    ramp_max_s: float = 10.0
    hold_min_s: float = 3.0
    hold_max_s: float = 12.0
    reach_min: float = 0.5        # share of the joint box the largest joint reaches
    reach_max: float = 0.9

    def as_dict(self) -> dict:
        return asdict(self)


def axis_directions(design) -> np.ndarray:
    """Joint deflections (6 axes x 6 joints) that load each wrench axis alone at rest, each
    scaled so that its largest joint deflection is 1."""
    params = model.Params.from_design(design)
    h = 1e-6
    jac = np.stack([(model.wrench(params, np.eye(6)[j] * h) - model.wrench(params,
                                                                          -np.eye(6)[j] * h))
                    / (2 * h) for j in range(6)], axis=-1)                 # (6 wrench, 6 joints)
    dirs = np.linalg.solve(jac, np.diag(full_scale(design))).T               # (axis, joint)
    return dirs / np.abs(dirs).max(axis=1, keepdims=True)


class AxisPushes:
    """One axis at a time (see the module docstring); ``evaluate(t) -> (q, qd)``."""

    description = "one axis at a time (Fig. 9 style pushes)"

    def __init__(self, design, duration_s: float, rng: np.random.Generator,
                 settings: PushSettings = PushSettings()):
        if not duration_s > 0:
            raise ValueError(f"the pushes need a positive duration, got {duration_s!r} s")
        self.settings = s = settings
        dirs = axis_directions(design)
        limit = design.joint_limit_rad
        starts, lengths, frm, to = [], [], [], []
        stretch = duration_s / 6.0
        rest = np.zeros(6)
        for axis in range(6):
            now, end, sign = axis * stretch, (axis + 1) * stretch, 1.0
            cycles = []
            while sum(sum(c) for _, c in cycles) < end - now:
                push = sign * rng.uniform(s.reach_min, s.reach_max) * limit * dirs[axis]
                cycles.append((push, [rng.uniform(s.ramp_min_s, s.ramp_max_s),
                                      rng.uniform(s.hold_min_s, s.hold_max_s),
                                      rng.uniform(s.ramp_min_s, s.ramp_max_s),
                                      rng.uniform(s.hold_min_s, s.hold_max_s)]))
                sign = -sign
            # The pushes fill the stretch exactly, a little faster than drawn: each returns to
            # rest inside its axis's stretch, the moves follow one another without overlap,
            # and the path is continuous.
            scale = (end - now) / sum(sum(c) for _, c in cycles)
            for push, cycle in cycles:
                for target, length in zip((push, push, rest, rest), cycle):
                    starts.append(now), lengths.append(length * scale)
                    frm.append(to[-1] if to else rest), to.append(target)
                    now += length * scale
        self.starts = np.array(starts)
        self.lengths = np.array(lengths)
        self.origins = np.array(frm)
        self.targets = np.array(to)

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return quintic_moves(np.asarray(t, dtype=float), self.starts, self.lengths,
                             self.origins, self.targets)


__all__ = ["AxisPushes", "PushSettings", "axis_directions"]
