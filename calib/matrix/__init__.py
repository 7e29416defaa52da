"""M1 — the sensor's force→displacement matrix C (3×3, mm/N) with honest uncertainty.

Public API: :func:`fit_matrix`, :class:`MatrixPrior`, :class:`CalibrationData`,
:func:`read_calibration_csv`, :func:`predict_u`. See :mod:`.fit` for the choice of
model (regress F on U, invert), :mod:`.exact` for the conjugate derivation.
"""
from feeler.calib.matrix.data import (CalibrationData, DesignWarning, read_calibration_csv,
                                      weak_directions)
from feeler.calib.matrix.fit import BACKENDS, MODELS, NOISES, NotSampled, fit_matrix
from feeler.calib.matrix.predict import predict_u
from feeler.calib.matrix.prior import MatrixPrior

__all__ = ["CalibrationData", "DesignWarning", "read_calibration_csv", "weak_directions",
           "fit_matrix", "NotSampled", "MODELS", "NOISES", "BACKENDS", "predict_u", "MatrixPrior"]
