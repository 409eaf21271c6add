"""Fitting a unit's calibration from a calibration log (``delta6 calibrate``,
``docs/calibration.md``). The file format and the calibrated model live in ``delta6.core``
(``calibration``, ``calibrated``): the host stream and codegen use them without this package.
"""
from delta6.calibration.fit import CalibrationFit, calibrate

__all__ = ["CalibrationFit", "calibrate"]
