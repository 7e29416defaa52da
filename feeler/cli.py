"""The ``feeler`` command: one sub-command per module in ``feeler.commands``.

Each command module defines ``NAME`` (the sub-command), ``HELP`` (one line) and
``register(parser)`` which adds its arguments and sets ``parser.set_defaults(run=...)``.
Command modules import heavy libraries (PyMC, OpenCV, WeasyPrint) only inside ``run``,
so ``feeler --help`` stays fast.
"""
from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys

from feeler.errors import FeelerError, InputError

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    import feeler
    import feeler.commands as pkg

    parser = argparse.ArgumentParser(
        prog="feeler",
        description="Tactile sensing lab suite: simulate scans, decode them with the FA-I "
                    "neuron model, calibrate sensors and neurons with Bayesian posteriors, "
                    "and report robot vs human discrimination.",
    )
    parser.add_argument("--version", action="version", version=f"feeler {feeler.__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more log output (-v info, -vv debug, including every device exchange)")
    sub = parser.add_subparsers(title="commands", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"feeler.commands.{info.name}")
        cmd = sub.add_parser(module.NAME, help=module.HELP, description=module.__doc__,
                             formatter_class=argparse.RawDescriptionHelpFormatter)
        module.register(cmd)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=[logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)],
                        format="%(levelname)s %(name)s: %(message)s")
    run = getattr(args, "run", None)
    if run is None:
        parser.print_help()
        return 2
    try:
        return int(run(args) or 0)
    except InputError as exc:
        print(f"feeler: error: {exc}", file=sys.stderr)
        return 2
    except FeelerError as exc:
        print(f"feeler: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("feeler: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
