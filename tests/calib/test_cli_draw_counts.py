"""calibrate neuron and calibrate sensor refuse draw counts their verdict cannot judge, before
any work, as the psychophysics fits do (an outside audit: calibrate neuron --chains 1
--draws 10 ran, then failed with 52 problems, R-hat nan among them)."""
import pytest

from feeler.cli import main
from tests.cli._run import refused_in_one_line

# DATASET need not exist: the counts are checked before it is read
CASES = {
    "neuron one chain": (["calibrate", "neuron", "no-data", "--chains", "1", "--draws", "10"],
                         ["--chains=1", "at least 2", "R-hat"]),
    "neuron nuts one chain": (["calibrate", "neuron", "no-data", "--backend", "nuts", "--chains", "1"], ["--chains=1"]),
    "neuron 4 x 50": (["calibrate", "neuron", "no-data", "--draws", "50"], ["--draws=50", "at least 100 with 4 chains"]),
    "neuron 200 x 3": (["calibrate", "neuron", "no-data", "--chains", "200", "--draws", "3"] ,
                       ["--chains=200", "at most 64"]),
    "neuron 40 x 3": (["calibrate", "neuron", "no-data", "--chains", "40", "--draws", "3"],
                      ["--draws=3", "at least 10 with 40 chains"]),
    "sensor one chain": (["calibrate", "sensor", "no-data", "--chains", "1"], ["--chains=1", "at least 2"]),
    "sensor 2 x 100": (["calibrate", "sensor", "no-data", "--chains", "2", "--draws", "100"],
                       ["--draws=100", "at least 200 with 2 chains"]),
    "sensor nuts 4 x 20": (["calibrate", "sensor", "no-data", "--backend", "nuts", "--draws", "20"], ["--draws=20"]),
    "sensor emcee 32 walkers x 5": (["calibrate", "sensor", "no-data", "--backend", "emcee", "--draws", "5"],
                                    ["--draws=5", "at least 13 with 32 chains"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_too_few_draws_are_refused_before_any_work(capsys, tmp_path, monkeypatch, case):
    monkeypatch.chdir(tmp_path)
    argv, needles = CASES[case]
    refused_in_one_line(capsys, argv, *needles)


def test_emcee_neuron_is_not_held_to_chains_and_draws(capsys, tmp_path, monkeypatch):
    """calibrate neuron --backend emcee runs its own walkers (--emcee-steps): the counts are not its."""
    monkeypatch.chdir(tmp_path)
    assert main(["calibrate", "neuron", "no-data", "--backend", "emcee"]) == 2
    assert "no-data" in capsys.readouterr().err                  # the dataset's error, not a count's
