"""The tool transform in Python (the firmware's ``delta6_toolframe.*`` is checked against it):
the wrench at the origin of frame {E}, in {E}'s axes, moved to a tool point ``p`` (m, in {E})
and into axes rotated by roll, pitch, yaw (rad; R = Rz(yaw) Ry(pitch) Rx(roll), the tool's axes
expressed in {E}):

    F_tool = R^T F,   M_tool = R^T (M - p x F)
"""
from __future__ import annotations

import numpy as np


def rotation(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) for (..., 3) angles: (..., 3, 3)."""
    r, p, y = np.moveaxis(np.asarray(rpy, dtype=float), -1, 0)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
        np.stack([-sp, cp * sr, cp * cr], -1)], -2)


def to_tool(wrench, translation, rpy) -> np.ndarray:
    """(..., 6) wrenches at {E}'s origin -> at the tool point, in the tool's axes."""
    wrench = np.asarray(wrench, dtype=float)
    f, m = wrench[..., :3], wrench[..., 3:]
    rt = np.swapaxes(rotation(rpy), -1, -2)
    m_p = m - np.cross(np.asarray(translation, dtype=float), f)
    return np.concatenate([np.einsum("ij,...j->...i", rt, f),
                           np.einsum("ij,...j->...i", rt, m_p)], axis=-1)
