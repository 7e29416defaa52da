"""Device emulators speaking real protocols, for tests and ``feeler emulate``."""
from feeler.hardware.emulators.faults import Fault, parse_fault
from feeler.hardware.emulators.grbl import GrblConfig, GrblEmulator
from feeler.hardware.emulators.pty_server import EmulatorProcess, emulator_process, serve_pty

__all__ = ["Fault", "parse_fault", "GrblConfig", "GrblEmulator", "EmulatorProcess",
           "emulator_process", "serve_pty"]
