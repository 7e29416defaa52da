"""Run a device emulator on a pseudo-terminal and print its device path.

  feeler emulate stage                       # a Grbl 1.1h stage; prints e.g. /dev/pts/7
  feeler emulate stage --fault drop:reply=ok,nth=3 --fault alarm:code=1,x_mm=-50
  feeler emulate stage --setting 22=1 --setting 20=1   # homing and soft limits: boots locked
  feeler emulate firmware runs/grbl/grbl/grbl-sim/grbl_sim.exe   # the real Grbl 1.1h (grbl-sim)

Open the printed path with any serial program (or `feeler acquire --stage PATH`) exactly
as a real /dev/ttyUSB0. It starts with Grbl 1.1h's default settings (500 mm/min, 10 mm/s²,
200 mm of travel per axis), changed by the options below; machine positions follow Grbl's
convention (soft limits, when enabled, on [-travel, 0]). Serves until Ctrl-C or SIGTERM.
Fault specs are
KIND[:key=value,...] with KIND one of delay, drop, garble, truncate, alarm, vanish, lose (a line
from the host lost on the way) and keys
reply (any, ok, error, status, alarm, banner, msg, setting), nth (1-based or none),
p (probability when nth=none), delay_s, code, x_mm, y_mm, z_mm, after_s.

`feeler emulate firmware EXE` serves the real Grbl 1.1h firmware instead: EXE is the
grbl_sim.exe that `bash ../shared/grbl-sim/build.sh DIR` builds (and prints), run on one CPU
in a working directory of its own (--workdir keeps its settings, $$, in EEPROM.DAT there;
default: a fresh one, Grbl's defaults). The path is printed once the firmware has booted and
answered a status query. It moves in about real time (slower on a loaded machine).
"""
from __future__ import annotations

import signal
import sys

NAME = "emulate"
HELP = "run a device emulator (Grbl stage), or the real Grbl firmware (grbl-sim), on a pseudo-terminal"
__all__ = ["NAME", "HELP", "register", "run_stage", "run_firmware"]


def register(parser) -> None:
    sub = parser.add_subparsers(title="devices", metavar="DEVICE")
    stage = sub.add_parser("stage", help="Grbl 1.1 stage controller",
                           description="Serve a Grbl 1.1 stage emulator on a pty; prints its path.")
    stage.add_argument("--fault", action="append", default=[], metavar="SPEC",
                       help="inject a fault, KIND[:key=value,...] (repeatable)")
    stage.add_argument("--seed", type=int, default=0, help="seed of random faults (default 0)")
    stage.add_argument("--travel-mm", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(200.0, 200.0, 200.0), help="$130-$132: travel per axis (default 200)")
    stage.add_argument("--max-rate-mm-min", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(500.0, 500.0, 500.0), help="$110-$112: per-axis maximum rate (default 500)")
    stage.add_argument("--accel-mm-s2", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(10.0, 10.0, 10.0), help="$120-$122: per-axis acceleration (default 10)")
    stage.add_argument("--start-mm", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(0.0, 0.0, 0.0), help="machine position at power-up (default 0 0 0)")
    stage.add_argument("--setting", action="append", default=[], metavar="N=VALUE",
                       help="any other Grbl setting at power-up, e.g. 22=1 (repeatable)")
    stage.set_defaults(run=run_stage)
    firmware = sub.add_parser("firmware", help="the real Grbl 1.1h firmware (grbl-sim) on a pty",
                              description="Serve grbl-sim's grbl_sim.exe (the unchanged Grbl 1.1h firmware as a host "
                                          "program; build it with `bash ../shared/grbl-sim/build.sh DIR`) on a pty; "
                                          "prints its path once the firmware answers.")
    firmware.add_argument("exe", metavar="EXE", help="grbl_sim.exe, as build.sh prints it")
    firmware.add_argument("--workdir", metavar="DIR", default=None,
                          help="the firmware's working directory, where it keeps its settings (EEPROM.DAT); "
                               "default: a fresh temporary one (Grbl's default settings), removed at the end")
    firmware.set_defaults(run=run_firmware)


def _setting(spec: str) -> tuple[int, float]:
    from feeler.errors import ArgumentError
    from feeler.hardware.emulators.config import GRBL_DEFAULTS

    number, _, value = spec.partition("=")
    try:
        pair = int(number.lstrip("$")), float(value)
    except ValueError:
        raise ArgumentError("--setting", spec, "N=VALUE, e.g. 22=1") from None
    if pair[0] not in GRBL_DEFAULTS or pair[1] < 0:
        raise ArgumentError("--setting", spec, f"a Grbl 1.1h setting ({', '.join(map(str, GRBL_DEFAULTS))}) "
                            "with a value >= 0")
    return pair


def run_stage(args) -> int:
    from feeler.errors import ArgumentError
    from feeler.hardware.emulators import GrblConfig, GrblEmulator, parse_fault, serve_pty

    for name in ("travel_mm", "max_rate_mm_min", "accel_mm_s2"):
        values = getattr(args, name)
        if not all(v > 0 for v in values):
            raise ArgumentError(f"--{name.replace('_', '-')}", values, "three numbers > 0")
    config = GrblConfig(travel_mm=tuple(args.travel_mm), max_rate_mm_min=tuple(args.max_rate_mm_min),
                        accel_mm_s2=tuple(args.accel_mm_s2), start_mm=tuple(args.start_mm),
                        settings=tuple(_setting(spec) for spec in args.setting))
    faults = tuple(parse_fault(spec) for spec in args.fault)
    emulator = GrblEmulator(config, faults, args.seed)
    stop: list[int] = []
    signal.signal(signal.SIGTERM, lambda signum, _: stop.append(signum))

    def announce(path: str) -> None:
        print(path, flush=True)
        print(f"feeler: Grbl emulator on {path}; Ctrl-C to stop", file=sys.stderr, flush=True)

    try:
        serve_pty(emulator, announce, lambda: bool(stop))
    except KeyboardInterrupt:
        pass
    return 0


def run_firmware(args) -> int:
    import contextlib
    import tempfile

    from feeler.hardware.emulators.firmware import serve_firmware

    stop: list[int] = []
    signal.signal(signal.SIGTERM, lambda signum, _: stop.append(signum))

    def announce(path: str) -> None:
        print(path, flush=True)
        print(f"feeler: Grbl 1.1h firmware (grbl-sim) on {path}; Ctrl-C to stop", file=sys.stderr, flush=True)

    with contextlib.ExitStack() as stack:
        workdir = args.workdir or stack.enter_context(tempfile.TemporaryDirectory(prefix="grbl-sim-"))
        try:
            return serve_firmware(args.exe, workdir, announce, lambda: bool(stop))
        except KeyboardInterrupt:
            return 0
