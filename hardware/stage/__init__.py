"""Grbl 1.1 stage driver in three layers: transport (bytes), protocol (Grbl), device.

``Stage.open(port)`` is the entry point; errors are in :mod:`.errors`.
"""
from feeler.hardware.stage.device import Stage
from feeler.hardware.stage.errors import (PortError, ProtocolError, StageAlarm, StageDisconnected,
                                          StageError, StageLocked, StageTimeout)
from feeler.hardware.stage.limits import StageGeometry, StageLimits

__all__ = ["Stage", "StageLimits", "StageGeometry", "StageError", "StageTimeout", "StageAlarm",
           "ProtocolError", "StageDisconnected", "StageLocked", "PortError"]
