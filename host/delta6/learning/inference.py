"""A learned estimator served by onnxruntime (numpy and onnxruntime only: no torch here).

    est = LearnedEstimator("gru.onnx", design=load("designs/delta6.toml"))
    wrench = est.predict(read_log("run.csv"))        # (n, 6), one wrench per row
    live = est.streaming()                           # sample by sample, same numbers

A model made for another design (or over another calibration) is refused with one line; so is a
file that is not a readable ONNX model or not a Delta6 estimator.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from delta6.core.calibration import Calibration
from delta6.core.design import Design
from delta6.learning.bases import AnalyticalBase, CalibrationBase, NoBase
from delta6.learning.card import ModelCard, ModelFileError
from delta6.learning.streaming import StreamingEstimator
from delta6.learning.windows import nominal_rate, segment_starts, window_index
from delta6.link.logfile import LogData

#: Windows per onnxruntime call in batch evaluation (bounds memory, not the result).
CHUNK = 4096
#: A log's sample rate may differ from the model's by this fraction.
RATE_TOLERANCE = 0.02


def open_session(path: str | Path, threads: int = 1):
    """An onnxruntime session on the CPU; an unreadable file raises :class:`ModelFileError`."""
    import onnxruntime as ort

    path = Path(path)
    if path.is_dir():
        raise ModelFileError(f"{path}: a folder, not a model file")
    if not path.is_file():
        raise ModelFileError(f"{path}: no such file")
    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    options.inter_op_num_threads = 1
    options.log_severity_level = 3      # no warnings on the console
    try:
        return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    except Exception as exc:     # onnxruntime raises its own types for every kind of bad file
        raise ModelFileError(f"{path}: not a readable ONNX model ({_reason(exc)})") from None


def _reason(exc: Exception) -> str:
    """The first line of an onnxruntime error, short enough for a one-line message."""
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0][:160]


class LearnedEstimator:
    """An exported model with the base it was trained over; ``name`` is the file's stem (the
    row name of ``delta6 evaluate``)."""

    def __init__(self, path: str | Path, *, design: Design,
                 calibration: Calibration | None = None, threads: int = 1):
        self.path = Path(path)
        self.name = self.path.stem
        if self.path.suffix.lower() == ".json" and self.path.is_file():
            raise ModelFileError(f"{self.path}: an on-chip model file (delta6 train --target "
                                 "mcu) runs on the board (delta6 codegen --model, delta6 virtual "
                                 "--model) or in delta6 evaluate --model; here a host model "
                                 "(MODEL.onnx) is needed")
        self.session = open_session(self.path, threads)
        self.card = ModelCard.from_props(
            dict(self.session.get_modelmeta().custom_metadata_map), str(self.path))
        card = self.card
        if card.design_hash != design.hash32():
            raise ModelFileError(
                f"{self.path} was trained for design {card.design_name} "
                f"(0x{card.design_hash:08x}), not {design.name} (0x{design.hash32():08x})")
        self.base = self._base(design, calibration)
        self._check_graph()
        self.input_name = self.session.get_inputs()[0].name

    def _base(self, design: Design, calibration):
        card = self.card
        if card.base == "none":
            return NoBase()
        if card.base == "analytical":
            return AnalyticalBase(design)
        trained_over = f"{card.calibration_name} (0x{card.calibration_hash:08x})"
        if calibration is None:
            raise ModelFileError(f"{self.path} is a residual over calibration {trained_over}: "
                                 "give that calibration (--calibration CAL.toml)")
        if calibration.hash32() != card.calibration_hash:
            raise ModelFileError(f"{self.path} was trained over calibration {trained_over}, not "
                                 f"{calibration.name} (0x{calibration.hash32():08x})")
        return CalibrationBase(design, calibration, card.rate_hz)

    def _check_graph(self) -> None:
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        shape_in = inputs[0].shape if len(inputs) == 1 else None
        shape_out = outputs[0].shape if outputs else None
        if (shape_in is None or len(shape_in) != 3 or shape_in[1:] != [self.card.window, 6]
                or shape_out is None or len(shape_out) != 2 or shape_out[1] != 6
                # a batch fixed in the graph fails on any other number of windows
                or isinstance(shape_in[0], int) or isinstance(shape_out[0], int)):
            raise ModelFileError(f"{self.path}: the graph does not take (batch, "
                                 f"{self.card.window}, 6) windows to (batch, 6) wrenches")
        # float32 both ways: the windows are fed as float32, and an integer output would
        # truncate the wrench silently
        for what, arg in (("input", inputs[0]), ("output", outputs[0])):
            if arg.type != "tensor(float)":
                raise ModelFileError(f"{self.path}: the graph's {what} is {arg.type}, not "
                                     "tensor(float) (float32)")

    # -- evaluation --------------------------------------------------------------------------

    @property
    def window(self) -> int:
        return self.card.window

    @property
    def rate_hz(self) -> float:
        return self.card.rate_hz

    def network(self, inputs: np.ndarray) -> np.ndarray:
        """Standardised windows (b, window, 6) float32 -> standardised outputs (b, 6)."""
        try:
            return self.session.run(None, {self.input_name: inputs})[0]
        except Exception as exc:    # onnxruntime's own types, for a graph that cannot run
            raise ModelFileError(f"{self.path}: the model fails to run ({_reason(exc)})") from None

    def check_rate(self, t: np.ndarray, source: str = "the log") -> None:
        if len(t) < 2:
            return
        rate = nominal_rate(t)
        if abs(rate / self.rate_hz - 1) > RATE_TOLERANCE:
            raise ModelFileError(f"{source} is sampled at {rate:.4g} Hz; {self.path} was trained "
                                 f"at {self.rate_hz:.4g} Hz (its window spans "
                                 f"{self.window / self.rate_hz:.3g} s)")

    def predict_arrays(self, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The wrench at every row (n, 6); NaN where the window holds a missing angle."""
        t = np.asarray(t, dtype=float)
        theta = np.asarray(theta, dtype=float)
        index = window_index(segment_starts(t, self.rate_hz), self.window)
        out = np.full((len(t), 6), np.nan)
        for start in range(0, len(t), CHUNK):
            win = theta[index[start:start + CHUNK]]
            ok = np.isfinite(win).all(axis=(1, 2))
            if ok.any():
                z = self.network(self.card.norm.inputs(win[ok]))
                out[start:start + CHUNK][ok] = self.card.norm.wrench(z)
        return out + self.base.batch(t, theta)

    def predict(self, log: LogData) -> np.ndarray:
        """The estimator protocol of ``delta6 evaluate``: one wrench per log row."""
        self.check_rate(log.t, "the log")
        return self.predict_arrays(log.t, log.theta)

    def streaming(self) -> StreamingEstimator:
        """A fresh sample-by-sample estimator on this model (its own window and its own copy of
        the base, whose state it carries)."""
        return StreamingEstimator(self)
