"""What no model on the encoders can see: the link's travel inside a backlash's play.

While a joint's encoder stands still, its link can be anywhere inside the play (after a
reversal, or while a small dither turns it back and forth without reaching a flank), and the
encoder says nothing about where. The backlash family models the play as well as the counts
allow; the rest of its error is left to the ladder's last step. Removing the play itself (a
tighter magnet holder) takes that rest away too. The reference wrench shows where the link
was: per sample, the travel of each standing joint, bounded by its fitted play, that best
explains the leftover is taken out. A joint whose encoder moved is on a flank, where the
backlash family is right, and is left alone, so other effects' leftover is not absorbed
outside the dwells, and inside them by at most the play's share. The travel is fitted to the
leftover averaged over +-``SMOOTH_S``: the link moves as smoothly as the robot does, while the
reference's noise is white, and with all six encoders standing (a hold without dither) six
unknowns would otherwise absorb any leftover whole, noise included.
"""
from __future__ import annotations

import numpy as np

from delta6.core.model import ENCODER_COUNT_RAD, wrench
from delta6.diagnosis import sensitivity
from delta6.diagnosis.data import PIECE, GapData
from delta6.diagnosis.signals import moving_average

#: A joint stands still when its encoder moved less than half a count since the sample before.
STILL_RAD = 0.5 * ENCODER_COUNT_RAD
#: Coordinate-descent sweeps over the joints (six unknowns at most, well conditioned: a few
#: sweeps settle to well below the noise).
SWEEPS = 8
#: Half-width of the moving average the travel is fitted to, s (a robot's dither of up to
#: about a hertz loses a tenth of its amplitude; white noise two thirds at 50 Hz).
SMOOTH_S = 0.1


def standing(theta: np.ndarray) -> np.ndarray:
    """(n, 6) True where a joint's encoder has not moved since the sample before."""
    still = np.zeros(theta.shape, dtype=bool)
    still[1:] = np.abs(np.diff(theta, axis=0)) < STILL_RAD
    return still


def travel_in_play(jac: np.ndarray, leftover: np.ndarray, still: np.ndarray,
                   play_rad: np.ndarray, sweeps: int = SWEEPS) -> np.ndarray:
    """The travel of each standing joint (rad, (n, 6); 0 where the joint moved) within
    +-``play_rad`` that best explains ``leftover`` (n, 6) through ``jac`` (n, 6 wrench,
    6 joints), both in the same units: bounded least squares per sample, by coordinate
    descent."""
    n = len(leftover)
    travel = np.zeros((n, 6))
    rest = np.array(leftover, dtype=float, copy=True)
    norm = np.einsum("nij,nij->nj", jac, jac)
    for _ in range(sweeps):
        for j in range(6):
            if not play_rad[j] > 0:
                continue
            col = jac[:, :, j]
            old = travel[:, j]
            best = old + np.einsum("ni,ni->n", col, rest) / np.where(norm[:, j] > 0,
                                                                      norm[:, j], np.inf)
            new = np.where(still[:, j], np.clip(best, -play_rad[j], play_rad[j]), 0.0)
            rest -= col * (new - old)[:, None]
            travel[:, j] = new
    return travel


def without_play(data: GapData, leftover_fs: np.ndarray, play_rad) -> tuple[np.ndarray,
                                                                             np.ndarray]:
    """The leftover (FS-normalised, (n, 6)) with the standing joints' travel inside the play
    taken out, and the RMS travel per joint as a share of its play. Piece by piece: a long
    log's angle Jacobian is never held whole."""
    play = np.clip(np.nan_to_num(np.asarray(play_rad, dtype=float)), 0.0, None)
    out = np.empty_like(leftover_fs)
    still = standing(data.theta)
    smooth = moving_average(leftover_fs, int(round(SMOOTH_S / data.step)) if data.step > 0
                            else 0)
    sq = np.zeros(6)
    for a in range(0, len(data), PIECE):
        sl = slice(a, a + PIECE)
        theta = data.theta[sl]
        jac = sensitivity.angle_jacobian(data.params, theta, base=wrench(data.params, theta))
        jac /= data.fs[None, :, None]
        travel = travel_in_play(jac, smooth[sl], still[sl], play)
        out[sl] = leftover_fs[sl] - np.einsum("nij,nj->ni", jac, travel)
        sq += (travel ** 2).sum(axis=0)
    rms = np.sqrt(sq / max(len(data), 1))
    share = np.divide(rms, play, out=np.zeros(6), where=play > 0)
    return out, share
