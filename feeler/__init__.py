"""feeler — tactile sensing lab suite.

Kept light on purpose: importing ``feeler`` imports neither PyMC, OpenCV nor
WeasyPrint. Sub-packages: ``feeler.models`` (forward models), ``feeler.hardware``
(drivers and emulators), ``feeler.calib`` (Bayesian layer), ``feeler.reports``.
"""
from feeler.errors import FeelerError, InputError

__version__ = "0.1.0"
__all__ = ["FeelerError", "InputError", "__version__"]
