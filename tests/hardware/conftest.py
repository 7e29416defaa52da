"""Fixtures of the hardware tests: the real Grbl 1.1h firmware (grbl-sim) on a pty.

``firmware`` is one running firmware per test module (it keeps a core busy while it runs,
so it is stopped at the end of the module); each test starts from
:meth:`~grbl_firmware.Firmware.prepare` (machine zero, Grbl's defaults, idle). Skipped, with
the reason, where the sources or a C compiler are missing.
"""
import pytest
from grbl_firmware import Firmware, firmware_exe


@pytest.fixture(scope="module")
def firmware_module(tmp_path_factory):
    exe = firmware_exe()
    fw = Firmware(tmp_path_factory.mktemp("grbl-sim"), exe)
    try:
        yield fw
    finally:
        fw.stop()


@pytest.fixture
def firmware(firmware_module):
    """The module's firmware, reset to Grbl's defaults at machine zero."""
    firmware_module.prepare()
    return firmware_module
