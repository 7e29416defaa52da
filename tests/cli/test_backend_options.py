"""An option the chosen backend or mode would not use is refused in one line before any work,
as --eiv with the exact backend is (an outside audit: --nu 7 without --noise student,
--emcee-steps with the grid backend, --wait-s without --follow, --separate with Laplace and
--target-accept with the exact grid all ran and exited 0, the option silently ignored; so did
calibrate neuron --backend emcee with --chains or --draws, calibrate sensor --backend emcee with
--chains, or with --tune but no --draws, and --eiv --model forward; calibrate sensors --workers with
--scheduler)."""
import pytest

from feeler.cli import main
from tests.cli._run import refused_in_one_line

# DATASET, POSTERIOR and RUN need not exist: the options are checked before anything is read
CASES = {
    "sensor --nu without student noise": (["calibrate", "sensor", "no-data", "--nu", "7"],
                                          ["--nu=7.0", "needs --noise student"]),
    "sensor --stage-sd-mm without --eiv": (["calibrate", "sensor", "no-data", "--backend", "nuts", "--stage-sd-mm",
                                            "0.01"], ["--stage-sd-mm=0.01", "needs --eiv"]),
    "sensor --tune with exact": (["calibrate", "sensor", "no-data", "--tune", "500"],
                                 ["--tune=500", "needs --backend nuts or emcee"]),
    "neuron --emcee-steps with grid": (["calibrate", "neuron", "no-data", "--emcee-steps", "500"],
                                       ["--emcee-steps=500", "needs --backend emcee"]),
    "neuron --emcee-steps with nuts": (["calibrate", "neuron", "no-data", "--backend", "nuts", "--emcee-steps", "500"],
                                       ["--emcee-steps=500", "needs --backend emcee"]),
    "neuron --tune with grid": (["calibrate", "neuron", "no-data", "--tune", "500"], ["--tune=500", "needs --backend nuts"]),
    "neuron --tune with emcee": (["calibrate", "neuron", "no-data", "--backend", "emcee", "--tune", "500"],
                                 ["--tune=500", "needs --backend nuts", "--emcee-steps"]),
    "neuron --chains with emcee": (["calibrate", "neuron", "no-data", "--backend", "emcee", "--chains", "8"],
                                   ["--chains=8", "needs --backend grid or nuts", "emcee backend runs 32 walkers",
                                    "--emcee-steps"]),
    "neuron --draws with emcee": (["calibrate", "neuron", "no-data", "--backend", "emcee", "--draws", "500"],
                                  ["--draws=500", "needs --backend grid or nuts", "32 walkers"]),
    "neuron --emcee-steps names the grid's draws": (["calibrate", "neuron", "no-data", "--emcee-steps", "500"],
                                                    ["--emcee-steps=500", "the grid backend runs --chains × --draws"]),
    "sensor --chains with emcee": (["calibrate", "sensor", "no-data", "--backend", "emcee", "--chains", "8"],
                                   ["--chains=8", "needs --backend exact or nuts", "32 walkers"]),
    "sensor --tune with emcee without --draws": (["calibrate", "sensor", "no-data", "--backend", "emcee", "--tune",
                                                  "100"], ["--tune=100", "needs --draws with --backend emcee"]),
    "sensor --model forward with --eiv": (["calibrate", "sensor", "no-data", "--backend", "nuts", "--eiv", "--model",
                                           "forward"], ["--model='forward'", "not used with --eiv"]),
    "sensors --workers with --scheduler serial": (["calibrate", "sensors", "no-data", "--out", "o", "--scheduler",
                                                   "serial", "--workers", "1"],
                                                  ["--workers=1", "needs a LocalCluster", "run in this process"]),
    "sensors --workers with a scheduler's address": (["calibrate", "sensors", "no-data", "--out", "o", "--scheduler",
                                                      "tcp://127.0.0.1:1", "--workers", "2"],
                                                     ["--workers=2", "the scheduler's own workers"]),
    "decode --wait-s without --follow": (["decode", "no-fit", "no-run", "--wait-s", "5"],
                                         ["--wait-s=5.0", "needs --follow"]),
    "decode --poll-s without --follow": (["decode", "no-fit", "no-run", "--poll-s", "1"],
                                         ["--poll-s=1.0", "needs --follow"]),
    "psychophysics --separate with laplace": (["fit", "psychophysics", "no-data.csv", "--backend", "laplace",
                                               "--separate"], ["argument --separate:", "needs --backend nuts"]),
    "psychophysics --target-accept with exact": (["fit", "psychophysics", "no-data.csv", "--target-accept", "0.5"],
                                                 ["--target-accept=0.5", "needs --backend nuts"]),
    "psychophysics --tune with exact": (["fit", "psychophysics", "no-data.csv", "--tune", "50"],
                                        ["--tune=50", "needs --backend nuts"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_an_option_the_backend_ignores_is_refused(capsys, tmp_path, monkeypatch, case):
    monkeypatch.chdir(tmp_path)
    argv, needles = CASES[case]
    refused_in_one_line(capsys, argv, *needles)


@pytest.mark.parametrize("argv", [
    ["calibrate", "sensor", "no-data", "--backend", "nuts", "--noise", "student", "--nu", "7"],
    ["calibrate", "sensor", "no-data", "--backend", "nuts", "--eiv", "--stage-sd-mm", "0.01", "--tune", "500"],
    ["calibrate", "neuron", "no-data", "--backend", "emcee", "--emcee-steps", "500"],
    ["calibrate", "neuron", "no-data", "--backend", "nuts", "--tune", "500"],
    ["calibrate", "neuron", "no-data", "--backend", "grid", "--chains", "8", "--draws", "300"],
    ["calibrate", "neuron", "no-data", "--backend", "nuts", "--chains", "2", "--draws", "300", "--tune", "200"],
    ["calibrate", "sensor", "no-data", "--chains", "8", "--draws", "300"],
    ["calibrate", "sensor", "no-data", "--backend", "emcee", "--draws", "500", "--tune", "100"],
    ["calibrate", "sensor", "no-data", "--backend", "nuts", "--eiv", "--model", "inverse"],
    ["fit", "psychophysics", "no-data.csv", "--backend", "nuts", "--separate", "--target-accept", "0.9", "--tune", "500"],
])
def test_the_same_options_with_their_backend_get_to_the_data(capsys, tmp_path, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "needs --" not in err and "no-data" in err, err       # refused for the missing data, not an option
