"""Run a device emulator on a pseudo-terminal and print its device path.

  feeler emulate stage                       # a Grbl 1.1 stage; prints e.g. /dev/pts/7
  feeler emulate stage --fault drop:reply=ok,nth=3 --fault alarm:code=1,x_mm=50

Open the printed path with any serial program (or `feeler acquire --stage PATH`) exactly
as a real /dev/ttyUSB0. Serves until Ctrl-C or SIGTERM. Fault specs are
KIND[:key=value,...] with KIND one of delay, drop, garble, truncate, alarm, vanish and keys
reply (any, ok, error, status, alarm, banner, msg, setting), nth (1-based or none),
p (probability when nth=none), delay_s, code, x_mm, y_mm, z_mm, after_s.
"""
from __future__ import annotations

import signal
import sys

NAME = "emulate"
HELP = "run a device emulator (Grbl stage) on a pseudo-terminal"
__all__ = ["NAME", "HELP", "register", "run_stage"]


def register(parser) -> None:
    sub = parser.add_subparsers(title="devices", metavar="DEVICE")
    stage = sub.add_parser("stage", help="Grbl 1.1 stage controller",
                           description="Serve a Grbl 1.1 stage emulator on a pty; prints its path.")
    stage.add_argument("--fault", action="append", default=[], metavar="SPEC",
                       help="inject a fault, KIND[:key=value,...] (repeatable)")
    stage.add_argument("--seed", type=int, default=0, help="seed of random faults (default 0)")
    stage.add_argument("--travel-mm", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(200.0, 200.0, 50.0), help="soft limits [0, travel] per axis")
    stage.add_argument("--max-rate-mm-min", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(3000.0, 3000.0, 1000.0), help="per-axis maximum rate")
    stage.add_argument("--accel-mm-s2", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(500.0, 500.0, 200.0), help="per-axis acceleration")
    stage.add_argument("--start-mm", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       default=(0.0, 0.0, 0.0), help="position at power-up")
    stage.set_defaults(run=run_stage)
    parser.set_defaults(run=lambda args: parser.print_help() or 2)


def run_stage(args) -> int:
    from feeler.errors import ArgumentError
    from feeler.hardware.emulators import GrblConfig, GrblEmulator, parse_fault, serve_pty

    for name in ("travel_mm", "max_rate_mm_min", "accel_mm_s2"):
        values = getattr(args, name)
        if not all(v > 0 for v in values):
            raise ArgumentError(f"--{name.replace('_', '-')}", values, "three numbers > 0")
    config = GrblConfig(travel_mm=tuple(args.travel_mm), max_rate_mm_min=tuple(args.max_rate_mm_min),
                        accel_mm_s2=tuple(args.accel_mm_s2), start_mm=tuple(args.start_mm))
    faults = tuple(parse_fault(spec) for spec in args.fault)
    emulator = GrblEmulator(config, faults, args.seed)
    if not emulator.within_travel(config.start_mm):
        raise ArgumentError("--start-mm", args.start_mm, "inside [0, travel] on every axis")
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
