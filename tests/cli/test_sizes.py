"""Upper bounds of the size-like options, refused in one line before any work (an outside
audit: --n-tau 100000000 ran 300 s without output; --draws 1000000000 was a numpy
MemoryError traceback, for calibrate neuron after 55 s of work)."""
import os

import pytest

from tests.cli._run import refused_in_one_line

CPUS = max(2, os.cpu_count() or 1)


_refused = refused_in_one_line


# DATASET need not exist and --out lies under a file: the sizes are checked before anything
# is read or any work starts (without the check these fail on the input instead, at once)
CASES = {
    "fit finger-route --n-tau": (["fit", "finger-route", "no-data.csv", "--n-tau", 100000000],
                                 ["--n-tau=100000000", "at most 1000"]),
    "calibrate sensor --draws": (["calibrate", "sensor", "no-data", "--draws", 1000000000],
                                 ["--draws=1000000000", "at most 50000 with 4 chains", "200000"]),
    "calibrate neuron --draws": (["calibrate", "neuron", "no-data", "--draws", 100000000],
                                 ["--draws=100000000", "at most 50000"]),
    "calibrate neuron --draws with 64 chains": (["calibrate", "neuron", "no-data", "--chains", 64, "--draws", 4000],
                                                ["--draws=4000", "at most 3125 with 64 chains"]),
    "fit psychophysics --draws": (["fit", "psychophysics", "no-data.csv", "--draws", 100000000],
                                  ["--draws=100000000", "at most 50000"]),
    "fit psychophysics --chains": (["fit", "psychophysics", "no-data.csv", "--chains", 1000], ["--chains=1000", "at most 64"]),
    "calibrate neuron --tune": (["calibrate", "neuron", "no-data", "--tune", 10**9], ["--tune=1000000000", "at most 100000"]),
    "calibrate neuron --emcee-steps": (["calibrate", "neuron", "no-data", "--backend", "emcee", "--emcee-steps", 10**7],
                                       ["--emcee-steps=10000000", "at most 200000"]),
    "calibrate sensor emcee --draws": (["calibrate", "sensor", "no-data", "--backend", "emcee", "--draws", 10000],
                                       ["--draws=10000", "at most 6250 with --backend emcee", "32 walkers"]),
    "discriminate --n-scans": (["discriminate", "no-fit", "--n-scans", 1000000000],
                               ["--n-scans=1000000000", "at most 20000"]),
    "validate sbc --n": (["validate", "sbc", "--model", "matrix", "--n", 10**6, "--out", "taken/x"], ["--n=1000000", "at most 10000"]),
    "calibrate sensors --workers": (["calibrate", "sensors", "no-data", "--out", "taken/x", "--workers", 10**6],
                                    ["--workers=1000000", f"at most {CPUS}"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_size_beyond_its_bound_is_refused_first(capsys, tmp_path, monkeypatch, case):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taken").write_text("")
    argv, needles = CASES[case]
    _refused(capsys, argv, *needles)
    assert [p.name for p in tmp_path.iterdir()] == ["taken"]      # nothing written


def test_discriminate_refuses_draws_times_touches_beyond_memory(capsys, tmp_path, monkeypatch):
    """--n-draws × --n-scans is checked once the fit says how many draws it has, before a touch is simulated."""
    import feeler.calib.neuron.discriminate as disc
    import feeler.commands.discriminate as cmd

    def loaded(args):
        args.n_draws = 4000                           # a fit's 4 × 1000 draws, all used
        return object()

    def no_work(*a, **k):
        raise AssertionError("simulated touches before the check")

    monkeypatch.setattr(cmd, "load_checked", loaded)
    monkeypatch.setattr(disc, "Discriminator", no_work)
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["discriminate", "fit", "--n-draws", 4000, "--n-scans", 20000],
             "--n-scans=20000", "at most 5000 with 4000 posterior draws")


def test_sizes_at_their_bounds_pass_the_check():
    import argparse

    from feeler.commands import _checks

    ok = argparse.Namespace(command="calibrate neuron", chains=4, draws=50000, tune=100000, emcee_steps=200000,
                            n_tau=1000, n_scans=20000, n=10000, workers=_checks.max_workers())
    _checks.check_sizes(ok)
    sbc = argparse.Namespace(command="validate sbc", draws=999, n=200)      # its own 9-999
    _checks.check_sizes(sbc)
