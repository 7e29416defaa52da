"""The ``feeler`` command: every sub-command explains itself, and start-up stays light."""
import argparse
import subprocess
import sys

import pytest

from feeler.cli import build_parser, main

HEAVY = ("pymc", "pytensor", "cv2", "weasyprint", "skfem", "gmsh", "dask", "arviz")


def _commands(parser, prefix=()):
    """Every (sub-)sub-command path of the parser."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*prefix, name)
                yield from _commands(sub, (*prefix, name))


ALL = sorted(set(_commands(build_parser())))


def test_the_expected_commands_are_there():
    top = {c[0] for c in ALL}
    assert {"simulate", "demo", "emulate"} <= top


@pytest.mark.parametrize("path", ALL, ids=[" ".join(p) for p in ALL])
def test_every_subcommand_has_help(path, capsys):
    with pytest.raises(SystemExit) as info:
        main([*path, "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: feeler " + " ".join(path))
    assert len(out.splitlines()) > 2


@pytest.mark.parametrize("columns", ["60", "80", "100"])
@pytest.mark.parametrize("path", [(), *ALL], ids=["feeler", *(" ".join(p) for p in ALL)])
def test_help_never_breaks_a_line_at_a_hyphen(path, columns, capsys, monkeypatch):
    """argparse's formatter wrapped after hyphens: `feeler skin figures --help` gave its
    example as "feeler skin figures datasets-" / "synthetic/finger-steps.toml ...", and
    options read "--no-" / "progress", "four-" / "plates" (an outside walk-through)."""
    import re

    monkeypatch.setenv("COLUMNS", columns)
    with pytest.raises(SystemExit):
        main([*path, "--help"])
    lines = capsys.readouterr().out.splitlines()
    assert not [ln for ln in lines if re.search(r"\w-$", ln)]
    for ln in (ln for ln in lines if "Example:" in ln or ln.strip().startswith("feeler ")):
        assert not ln.rstrip().endswith(("feeler", "--out")), ln
    if path == ("skin", "figures"):
        assert "    feeler skin figures datasets-synthetic/finger-steps.toml --out runs/finger-figs" in lines


@pytest.mark.parametrize("argv, words", [
    (["validate", "sbc", "--model", "matrix", "--n", "abc"], "argument --n: invalid int value: 'abc' (see "
                                                            "`feeler validate sbc --help`)"),
    (["classify", "--bogus"], "the following arguments are required: POSTERIOR, SCANS"),
    (["validate", "sbc", "--model", "matrix", "--draws", "0"], "--draws=0: 9 to 999 posterior draws"),
    # the fits draw 999: --draws 1000 failed after a dataset's fit as "argument n_draws=1000"
    (["validate", "sbc", "--model", "neuron", "--draws", "1000"], "--draws=1000: 9 to 999 posterior draws per "
                                                                  "dataset (ranks 0..draws; each fit draws 999"),
])
def test_argument_errors_are_one_line(argv, words, capsys):
    """argparse printed its usage block and 'feeler validate sbc: error:'; validate's --draws 0
    said '>= 1' where its own check wants 9 (an outside audit)."""
    try:
        code = main(argv)                   # the suite's own checks return 2
    except SystemExit as info:              # argparse's exit
        code = info.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].startswith("feeler: error: ") and words in err[-1], err
    assert not any(ln.startswith("usage:") for ln in err)


GROUPS = sorted({p[:-1] for p in ALL if len(p) > 1})


@pytest.mark.parametrize("group", GROUPS, ids=[" ".join(g) for g in GROUPS])
def test_a_group_without_its_command_names_them_in_one_line(group, capsys):
    """`feeler calibrate` alone said "feeler calibrate: fitting (loading libraries) ..." and
    then printed its whole help (an outside walk-through)."""
    choices = [p[-1] for p in _commands(build_parser()) if p[:-1] == group]        # in the parser's order
    assert main(list(group)) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1 and "loading libraries" not in err
    names = ", ".join(choices[:-1]) + f" or {choices[-1]}" if len(choices) > 1 else choices[0]
    assert err == (f"feeler: error: `feeler {' '.join(group)}` needs one of its commands: {names} "
                   f"(see `feeler {' '.join(group)} --help`)\n")


def test_no_command_prints_help_and_exits_2(capsys):
    assert main([]) == 2
    assert "commands" in capsys.readouterr().out


def test_import_and_help_stay_light():
    code = ("import sys, feeler, feeler.cli; feeler.cli.build_parser(); "
            f"print([m for m in {HEAVY!r} if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_python_dash_m_feeler_is_the_command():
    out = subprocess.run([sys.executable, "-m", "feeler", "--version"], capture_output=True,
                         text=True, check=True)
    assert out.stdout.startswith("feeler ")


def test_a_ctrl_c_while_the_interpreter_shuts_down_is_ignored(tmp_path):
    """A command has ended (its outputs written, its status set); a Ctrl-C while the
    libraries' atexit handlers run printed a KeyboardInterrupt traceback from dask's after
    'wrote …'. Here an atexit handler that runs after feeler's sends SIGINT to the process."""
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import atexit, os, signal, sys, time
        def late():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.2)
            print("shut down quietly", flush=True)
        atexit.register(late)              # registered first: runs after the handlers registered later
        from feeler.cli import main
        sys.exit(main(["classify", "no-such-fit", "no-such-scans"]))
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    assert "shut down quietly" in done.stdout and "KeyboardInterrupt" not in done.stderr, done.stderr


def test_validate_sbc_help_states_the_range_of_n_it_takes(capsys):
    """--help said "(default 200, at most 10000)" while --n below 10 was refused."""
    import re

    with pytest.raises(SystemExit):
        main(["validate", "sbc", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    lo, hi = map(int, re.search(r"--n N simulated datasets, (\d+)-(\d+) \(default 200", help_text).groups())
    assert (lo, hi) == (10, 10000)
    for n in (lo - 1, hi + 1):
        assert main(["validate", "sbc", "--model", "matrix", "--n", str(n), "--no-progress"]) == 2
        assert f"--n={n}: " in capsys.readouterr().err
