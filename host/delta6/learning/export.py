"""Export a trained network to ONNX (torch's dynamo exporter, which needs onnxscript) with its
model card in ``metadata_props``; the batch dimension stays free."""
from __future__ import annotations

import contextlib
import io
import logging
import warnings
from pathlib import Path

import numpy as np
import onnx
import torch

from delta6.core.errors import UserError
from delta6.learning.card import ModelCard

INPUT = "window"
OUTPUT = "wrench"


def export(module: torch.nn.Module, card: ModelCard, path: str | Path) -> Path:
    """Write ``path`` (the caller makes it atomic: ``learning.fit.write`` checks the export
    under a temporary name before it replaces anything)."""
    path = Path(path)
    module.eval()
    example = torch.zeros(2, card.window, 6)
    batch = torch.export.Dim("batch", min=1)
    chatter = io.StringIO()
    try:
        # The exporter reports its graph passes on stdout; keep the console for our own lines.
        with contextlib.redirect_stdout(chatter), contextlib.redirect_stderr(chatter), \
                _quiet("torch.onnx"), warnings.catch_warnings():
            warnings.simplefilter("ignore")     # the exporter's notes about torch internals
            program = torch.onnx.export(module, (example,), dynamo=True, input_names=[INPUT],
                                        output_names=[OUTPUT],
                                        dynamic_shapes=({0: batch},), optimize=True)
        proto = program.model_proto
        for key, value in card.to_props().items():
            entry = proto.metadata_props.add()
            entry.key, entry.value = key, value
        proto.doc_string = "Delta6 learned estimator: " + card.describe()
        onnx.checker.check_model(proto)
        onnx.save_model(proto, str(path))
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None
    return path


def max_difference(module: torch.nn.Module, path: str | Path, inputs: np.ndarray) -> float:
    """Largest |onnxruntime - torch| over ``inputs`` (standardised windows)."""
    from delta6.learning.inference import open_session
    from delta6.learning.training import predict

    session = open_session(path)
    onnx_out = session.run(None, {session.get_inputs()[0].name: inputs.astype(np.float32)})[0]
    return float(np.max(np.abs(onnx_out - predict(module, inputs.astype(np.float32)))))


@contextlib.contextmanager
def _quiet(logger_name: str):
    """The exporter logs warnings about optional packages it does not need (torchvision)."""
    logger = logging.getLogger(logger_name)
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)
