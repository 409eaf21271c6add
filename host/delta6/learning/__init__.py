"""Learned estimators (docs/learning.md): windows of encoder readings to the wrench, trained
from a calibration log with torch (the ``train`` extra), exported to ONNX, served with numpy
and onnxruntime only.

    from delta6.learning import LearnedEstimator
    est = LearnedEstimator("gru.onnx", design=design)
    est.predict(log)                 # (n, 6), one wrench per row
    live = est.streaming()           # live.update(t, theta) -> (6,), the same numbers

Nothing imported here imports torch; training lives in :mod:`delta6.learning.fit`, and the
small integer residual model the microcontroller runs in :mod:`delta6.learning.mcu`.
"""
from delta6.learning.card import ModelCard, ModelFileError
from delta6.learning.inference import LearnedEstimator
from delta6.learning.streaming import StreamingEstimator
from delta6.learning.windows import WINDOW, Normalisation

__all__ = ["ModelCard", "ModelFileError", "LearnedEstimator", "StreamingEstimator", "WINDOW",
           "Normalisation"]
