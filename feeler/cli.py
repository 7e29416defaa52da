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
import textwrap
import warnings
from pathlib import Path

from feeler.errors import ArgumentError, FeelerError, InputError

__all__ = ["main", "build_parser"]


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """--help wrapped at spaces only. argparse's formatter also broke lines after a hyphen,
    so a path, an option or an example command copied from --help came in two pieces
    ("feeler skin figures datasets-" / "synthetic/finger-steps.toml", "--no-" /
    "progress"). A description written in lines (a command's docstring) is printed as
    written; a one-line description is filled, with its "Example: COMMAND" on lines of
    its own, the command never wrapped."""

    def _split_lines(self, text, width):
        text = self._whitespace_matcher.sub(" ", text).strip()
        return textwrap.wrap(text, width, break_on_hyphens=False, break_long_words=False)

    def _fill_text(self, text, width, indent):
        if "\n" in text.strip():
            return super()._fill_text(text, width, indent)
        prose, _, example = text.partition("Example: ")
        prose = self._whitespace_matcher.sub(" ", prose).strip()
        filled = textwrap.fill(prose, width, initial_indent=indent, subsequent_indent=indent,
                               break_on_hyphens=False, break_long_words=False)
        return filled + (f"\n\n{indent}Example:\n{indent}    {example.strip()}" if example.strip() else "")


class _Parser(argparse.ArgumentParser):
    """argparse with the suite's one-line errors: ``feeler: error: <what> (see PROG --help)``
    instead of the usage block and ``PROG: error:`` (a value of the wrong type, an unknown
    option); exit status 2 as before. Sub-commands' parsers are of this class too, and
    all of them format their help with :class:`HelpFormatter`."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"feeler: error: {message} (see `{self.prog} --help`)\n")


def build_parser() -> argparse.ArgumentParser:
    import feeler
    import feeler.commands as pkg

    parser = _Parser(
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
        cmd = sub.add_parser(module.NAME, help=module.HELP, description=module.__doc__)
        module.register(cmd)
        _name_commands(cmd, module.NAME)
    return parser


def _name_commands(parser: argparse.ArgumentParser, path: str) -> None:
    """``args.command`` = the full sub-command path ("calibrate sensor"), at every depth;
    ``args.group_of`` = the sub-commands of a group given none of them ("calibrate" alone:
    ("sensor", "neuron", "sensors")), None once one is given."""
    groups = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    parser.set_defaults(command=path, group_of=tuple(n for a in groups for n in a.choices) or None)
    for action in groups:
        for name, sub in action.choices.items():
            _name_commands(sub, f"{path} {name}")


def _no_sub_command(command: str, choices: tuple[str, ...]) -> int:
    """``feeler calibrate`` alone: one line naming its sub-commands, exit 2 (it said
    "fitting (loading libraries) ..." and then printed its whole help)."""
    names = ", ".join(choices[:-1]) + f" or {choices[-1]}" if len(choices) > 1 else choices[0]
    print(f"feeler: error: `feeler {command}` needs one of its commands: {names} "
          f"(see `feeler {command} --help`)", file=sys.stderr)
    return 2


# what the first line says while the heavy libraries load (default: "loading ...")
STARTING = {
    "calibrate": "fitting",
    "classify": "classifying the scans",
    "discriminate": "simulating 2AFC discrimination with the posterior",
    "decode": "decoding the run",
    "fit": "fitting",
    "simulate": "simulating",
    "acquire": "starting the acquisition",
    "skin": "running the skin model",
    "validate": "simulation-based calibration",
    "demo": "running the demo chain",
    "emulate": "starting the emulator",
}


def _first_line(args) -> None:
    """One line on stderr before any heavy import, so the user knows the command runs."""
    command = getattr(args, "command", None)
    if command is None or command == "report" or getattr(args, "progress", None) is False:
        return                                   # report prints its own first line
    what = STARTING.get(command.split()[0], "working")
    # the positional the command works on: discriminate --scene X still simulates with the posterior
    target = next((getattr(args, k) for k in ("dataset", "scans", "run_dir", "posterior", "scene", "data", "plan")
                   if isinstance(getattr(args, k, None), str)), None)
    if target is None and isinstance(getattr(args, "datasets", None), list):
        target = f"{len(args.datasets)} dataset{'s' if len(args.datasets) != 1 else ''}"
    print(f"feeler {command}: {what}{' ' + target if target else ''} (loading libraries) ...",
          file=sys.stderr, flush=True)


#: counts a command checks itself, with larger minimums and its reasons (validate sbc: ranks need 9 draws)
OWN_CHECKS = {"validate sbc": ("n", "draws")}


def _check_before_work(args) -> None:
    """Output path and earlier results, before anything is computed (issue 16 item 3)."""
    own = OWN_CHECKS.get(getattr(args, "command", None) or "", ())
    for name, least in (("draws", 1), ("tune", 0), ("chains", 1), ("n_draws", 2), ("n", 1), ("seed", 0),
                        ("touch_seed", 0), ("workers", 1)):
        if name in own:
            continue
        value = getattr(args, name, None)
        if isinstance(value, int) and not isinstance(value, bool) and value < least:
            raise ArgumentError(f"--{name.replace('_', '-')}", value, f"an integer >= {least}")
    from feeler.commands._checks import check_sizes
    check_sizes(args)
    from feeler.scene import SEED_MAX

    for name in ("seed", "touch_seed"):      # a seed is recorded in TOML, whose integers are 64-bit
        value = getattr(args, name, None)
        if isinstance(value, int) and not isinstance(value, bool) and value > SEED_MAX:
            raise ArgumentError(f"--{name.replace('_', '-')}", value,
                                f"an integer from 0 to 2**63-1 = {SEED_MAX} (TOML's integer range; "
                                "scene.toml records the seed)")
    out = getattr(args, "out", None)
    if isinstance(out, str) and out:
        from feeler.commands._checks import check_out_dir
        check_out_dir(out, getattr(args, "out_files", ()), force=bool(getattr(args, "force", False)))


#: arguments of the library's functions that a command's option passes on under another name
_LIBRARY_NAMES = {"c0_mm_per_n": "c0", "all": "all_estimand"}


def _as_option(exc: Exception, parser: argparse.ArgumentParser) -> Exception:
    """``exc`` with a library argument's name (``rel_sd``) turned into the option the user
    typed (``--rel-sd``), when one of the commands has such an option."""
    if not isinstance(exc, ArgumentError) or exc.name.startswith("-"):
        return exc
    options, parsers = {}, [parser]
    while parsers:
        for action in parsers.pop()._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(action.choices.values())
            elif action.option_strings:
                options.setdefault(action.dest, max(action.option_strings, key=len))
    flag = options.get(_LIBRARY_NAMES.get(exc.name, exc.name))
    return exc if flag is None else ArgumentError(flag, exc.value, exc.allowed)


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """warnings.showwarning: ``feeler: warning: <message>`` on one line, no source path."""
    text = " ".join(str(message).split())
    print(f"feeler: warning: {text}", file=sys.stderr if file is None else file, flush=True)


def _quiet_third_parties(verbose: int) -> None:
    """Third-party log noise only with -v: none of dask.distributed's (here or in its worker
    processes, :mod:`feeler.calib.dask_logging`), PyMC's and pytensor's errors only."""
    from feeler.calib.dask_logging import quiet

    quiet(verbose)
    if verbose == 0:
        for name in ("pymc", "pytensor"):
            logging.getLogger(name).setLevel(logging.ERROR)


def _run_started(args) -> bool:
    """A command that takes --resume has written its run directory (its journal): a failure
    that came before (a port that is no Grbl board, a bad plan) has no run to resume."""
    out = getattr(args, "out", None)
    return getattr(args, "resume", None) is not None and bool(out) and (Path(out) / "journal.jsonl").is_file()


class _UserFormatter(logging.Formatter):
    """'feeler: warning: …' as the CLI prints its own lines, not 'WARNING feeler.acquire: …'
    (an outside audit: acquire's late-sample and bad-frame lines read as a log's)."""

    def format(self, record: logging.LogRecord) -> str:
        return f"feeler: {record.levelname.lower()}: {record.getMessage()}"


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    handler = logging.StreamHandler()    # a user's warning reads as the CLI's own lines; -v names the logger
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s") if args.verbose else
                         _UserFormatter())
    logging.basicConfig(level=[logging.WARNING, logging.INFO, logging.DEBUG][min(args.verbose, 2)],
                        handlers=[handler])
    if getattr(args, "group_of", None):                 # a group without its sub-command: no work line
        return _no_sub_command(args.command, args.group_of)
    run = getattr(args, "run", None)
    if run is None:
        parser.print_help()
        return 2
    _quiet_third_parties(args.verbose)
    _first_line(args)
    shown = warnings.showwarning
    warnings.showwarning = _one_line_warning
    try:
        _check_before_work(args)
        return int(run(args) or 0)
    except InputError as exc:
        print(f"feeler: error: {_as_option(exc, parser)}", file=sys.stderr)
        return 2
    except FeelerError as exc:
        resume = "; the run so far is kept: run the same command with --resume to continue" \
            if _run_started(args) and "--resume" not in str(exc) else ""
        print(f"feeler: failed: {exc}{resume}", file=sys.stderr)
        return 1
    except (FileExistsError, IsADirectoryError, NotADirectoryError, PermissionError, FileNotFoundError) as exc:
        where = exc.filename if exc.filename is not None else ""
        print(f"feeler: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        resume = " (run the same command with --resume to continue)" if _run_started(args) else ""
        print(f"feeler: interrupted{resume}", file=sys.stderr)
        return 130
    finally:
        warnings.showwarning = shown
        _quiet_exit()


_EXIT_QUIET = []


def _quiet_exit() -> None:
    """Ignore Ctrl-C while the interpreter shuts down, once the command has ended: its
    outputs are written and its exit status is set, and a Ctrl-C then (a user pressing it
    as the fit finished) printed a KeyboardInterrupt traceback from dask's own atexit
    handler after 'wrote …', exit 0. atexit runs the handlers last registered first, so
    this one, registered after the command imported its libraries, runs before theirs."""
    if not _EXIT_QUIET:
        import atexit
        import signal

        _EXIT_QUIET.append(True)
        atexit.register(signal.signal, signal.SIGINT, signal.SIG_IGN)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
