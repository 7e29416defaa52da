"""`feeler calibrate neuron`, `classify` and `discriminate` end to end on the shipped scene."""
import json
import re

import pytest

from feeler.calib.neuron.synth import FOUR_PLATES
from feeler.cli import main


@pytest.fixture(scope="module")
def run_and_fit(tmp_path_factory):
    root = tmp_path_factory.mktemp("m2")
    run, fit = root / "run", root / "fit"
    assert main(["simulate", str(FOUR_PLATES), "--out", str(run)]) == 0
    assert main(["calibrate", "neuron", str(run), "--out", str(fit), "--draws", "300", "--no-progress"]) == 0
    return run, fit


def test_calibrate_prints_the_checks_and_records_the_scene(run_and_fit, capsys):
    from feeler.calib.fit import load
    run, fit = run_and_fit
    attrs = load(fit).posterior["posterior"].attrs
    assert attrs["scene_toml"] == (run / "scene.toml").read_text()
    assert main(["calibrate", "neuron", str(run), "--draws", "300", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "decoder noise:" in out and "labels inside their 90 % interval per plate" in out and "verdict: ok" in out
    # a's unit as the report labels it (it said "mm per unit of window sum", the report "mm per unit strain")
    assert "a is in mm per unit strain (P, the peak window sum of |strain changes|, is a strain)" in out


def test_a_directory_of_one_file_per_scan_fits_as_its_scans_csv(run_and_fit, tmp_path, capsys):
    """A lab's one file per scan with the scene beside them: the same posterior as scans.csv,
    the scene recorded; without a scene, --length-mm is asked for, naming the directory."""
    import shutil

    import pandas as pd
    from feeler.calib.fit import load

    run, fit = run_and_fit
    lab = tmp_path / "lab"
    lab.mkdir()
    frame = pd.read_csv(run / "scans.csv")
    for sid, g in frame.groupby("scan_id"):
        g.drop(columns="scan_id").to_csv(lab / f"scan_{sid:03d}.csv", index=False)
    assert main(["calibrate", "neuron", str(lab), "--draws", "300", "--no-progress"]) == 2
    assert "the scan files of lab/ have no scene.toml with them" in capsys.readouterr().err
    shutil.copy(run / "scene.toml", lab / "scene.toml")
    assert main(["calibrate", "neuron", str(lab), "--out", str(tmp_path / "f"), "--draws", "300",
                 "--no-progress"]) == 0
    assert f"96 scans from {lab}, strain = U_y / 3 mm" in capsys.readouterr().out
    ours, theirs = load(tmp_path / "f").posterior, load(fit).posterior
    assert ours["posterior"].attrs["scene_toml"] == (run / "scene.toml").read_text()
    for name in ("a", "tau_s", "plate_sd_mm"):
        assert (ours["posterior"][name].values == theirs["posterior"][name].values).all(), name


def test_classify_and_discriminate_use_the_fit(run_and_fit, tmp_path, capsys):
    import pandas as pd
    run, fit = run_and_fit
    assert main(["classify", str(fit), str(run), "--n-draws", "50", "--out", str(tmp_path / "cls")]) == 0
    assert "classified as their labelled plate" in capsys.readouterr().out
    table = pd.read_csv(tmp_path / "cls" / "classification.csv")
    assert {"scan_id", "step_mm", "plate_mm", "p_0mm", "height_mm", "lo90_mm", "hi90_mm"} <= set(table.columns)
    assert ((table.lo90_mm <= table.height_mm) & (table.height_mm <= table.hi90_mm)).all()
    assert main(["discriminate", str(fit), "--pair", "0.1", "0.12", "--pair", "0.2", "0.25", "--n-scans", "40",
                 "--n-draws", "10", "--speeds", "0.5", "0.5", "--out", str(tmp_path / "d")]) == 0
    out = capsys.readouterr().out
    assert "the scene recorded in the fit" in out and "MC se" in out and "Weber fraction" in out
    # what P(correct) measures (an outside audit compared it with classify's reading of fresh pairs)
    assert "2AFC rule: the touch whose peak z is larger is called higher" in out
    assert out.count("note: pair height 0.25 mm lies outside the plates the fit was trained on") == 1
    d = json.loads((tmp_path / "d" / "discrimination.json").read_text())
    assert set(d["threshold_mm"]) >= {"mean", "lo95", "hi95", "found", "median", "mcse", "hi95_is_bound"}
    assert set(d["pairs"][0]) >= {"low_mm", "high_mm", "pc", "lo95", "hi95", "mcse"}
    assert d["pairs"][0]["lo95"] <= d["pairs"][0]["pc"] <= d["pairs"][0]["hi95"]
    # the notes reach the file the report reads (an outside review found the extrapolation said only
    # on the terminal, and the report marking a threshold outside the plates as reproduced)
    assert d["extrapolated"] is True
    assert any(n.startswith("note: pair height 0.25 mm lies outside the plates") for n in d["notes"])
    assert not any("reference" in n for n in d["notes"])           # the reference, 0.1 mm, is a trained plate


def test_refusals_and_errors(run_and_fit, tmp_path, capsys):
    run, fit = run_and_fit
    (fit / "verdict.json").write_text(json.dumps({"ok": False, "problems": ["a: R-hat 1.2 > 1.01"]}))
    try:
        assert main(["classify", str(fit), str(run)]) != 0                       # a failed fit is refused
        capsys.readouterr()
        assert main(["classify", str(fit), str(run), "--n-draws", "20", "--accept-failed"]) == 0
        err = capsys.readouterr().err          # used, but never silently (an outside audit)
        assert "failed its diagnostics (1 problem; the first: a: R-hat 1.2 > 1.01); --accept-failed" in err
        assert main(["discriminate", str(fit), "--pair", "0.1", "0.2", "--n-scans", "10", "--n-draws", "5",
                     "--accept-failed", "--no-progress", "--out", str(tmp_path / "d-failed")]) == 0
        assert "failed its diagnostics" in capsys.readouterr().err
        d = json.loads((tmp_path / "d-failed" / "discrimination.json").read_text())
        assert d["posterior_verdict"] == {"ok": False, "problems": ["a: R-hat 1.2 > 1.01"]}
        assert main(["classify", str(fit), str(run), "--n-draws", "1", "--accept-failed"]) == 2
    finally:
        (fit / "verdict.json").write_text(json.dumps({"ok": True, "problems": []}))
    assert main(["calibrate", "neuron", str(run), "--out", str(fit)]) == 2      # refuses to overwrite
    assert main(["calibrate", "neuron", str(tmp_path / "nothing.txt")]) == 2
    assert main(["calibrate", "neuron", str(run), "--emcee-steps", "5"]) == 2
    csv = tmp_path / "bare" / "scans.csv"
    csv.parent.mkdir()
    csv.write_text((run / "scans.csv").read_text())
    bare = tmp_path / "bare-fit"
    assert main(["calibrate", "neuron", str(csv), "--length-mm", "3", "--draws", "300", "--out", str(bare),
                 "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["discriminate", str(bare), "--n-scans", "10", "--n-draws", "5"]) == 2
    assert "--scene" in capsys.readouterr().err
    assert main(["discriminate", str(bare), "--scene", str(FOUR_PLATES), "--pair", "0.1", "0.2", "--n-scans", "10",
                 "--n-draws", "5", "--speeds", "0.5", "0.5"]) == 0


def test_a_csv_beside_another_kinds_scene_says_what_to_do(run_and_fit, tmp_path, capsys):
    """A scans CSV dropped into a sensor-calibration dataset: the scene.toml beside it is
    not its scene. It said "scene.toml must be a robot-scan scene", naming the scene file
    the user never gave; now the CSV, the scene's kind and the two ways out."""
    run, _ = run_and_fit
    cal = tmp_path / "cal"
    assert main(["simulate", str(FOUR_PLATES.with_name("sensor-calibration.toml")), "--out", str(cal)]) == 0
    csv = cal / "my_scans.csv"
    csv.write_text((run / "scans.csv").read_text())
    capsys.readouterr()
    assert main(["calibrate", "neuron", str(csv), "--length-mm", "3", "--out", str(tmp_path / "f")]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:")]
    assert len(err) == 1 and err[0].startswith("feeler: error: argument DATASET='")         # long paths are cut
    assert err[0].endswith("my_scans.csv': the scene.toml beside it is a 'sensor-calibration' scene, not the "
                           "robot-scan scene of these scans; move the CSV to a directory of its own (and give "
                           "--length-mm) or take that scene.toml away")
    assert not (tmp_path / "f").exists()


def test_another_kind_of_csv_is_named_for_what_it_is(run_and_fit, tmp_path, capsys):
    """A trial table or a calibration file given as scans: calibrate neuron said the scene
    beside it was 'not the robot-scan scene of these scans', and classify listed the
    missing columns. Both now say what the file is and which command reads it."""
    run, fit = run_and_fit
    trials = tmp_path / "psy"
    assert main(["simulate", str(FOUR_PLATES.with_name("psychophysics-2afc.toml")), "--out", str(trials)]) == 0
    capsys.readouterr()
    assert main(["calibrate", "neuron", str(trials / "trials.csv"), "--length-mm", "3", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"feeler: error: {trials / 'trials.csv'}: not robot scans: trials.csv is a psychophysics trial "
                   "table: `feeler fit psychophysics` and `feeler fit finger-route` fit it")
    assert main(["classify", str(fit), str(trials / "trials.csv"), "--n-draws", "20", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith(f"feeler: error: {trials / 'trials.csv'}: missing column(s) scan_id, t_s, uy_mm")
    assert err.endswith("; trials.csv is a psychophysics trial table: `feeler fit psychophysics` and "
                        "`feeler fit finger-route` fit it")


def test_a_mislabelled_scan_is_named_as_the_lab_wrote_it(run_and_fit, tmp_path, capsys):
    """One touch of the 0.2 mm plate labelled 0 mm fails the verdict, naming the scan as the
    file did: its text scan_id, or its file in a directory of one file per scan."""
    import shutil

    import pandas as pd

    run, _ = run_and_fit
    frame = pd.read_csv(run / "scans.csv")
    wrong = int(frame.loc[frame.step_mm == 0.2, "scan_id"].iloc[0])
    frame.loc[frame.scan_id == wrong, "step_mm"] = 0.0
    named = frame.assign(scan_id="touch-" + frame.scan_id.astype(str))
    (tmp_path / "named").mkdir()
    named.to_csv(tmp_path / "named" / "scans.csv", index=False)
    shutil.copy(run / "scene.toml", tmp_path / "named")
    assert main(["calibrate", "neuron", str(tmp_path / "named"), "--draws", "300", "--no-progress"]) == 1
    line = [ln for ln in capsys.readouterr().out.splitlines() if "step_mm:" in ln]
    assert len(line) == 1 and f"step_mm: scan_id 'touch-{wrong}' (labelled 0 mm) lies far outside" in line[0]
    assert "matches plate 0.2 mm" in line[0]
    files = tmp_path / "files"
    files.mkdir()
    for sid, scan in frame.groupby("scan_id"):
        scan.drop(columns="scan_id").to_csv(files / f"touch_{sid:03d}.csv", index=False)
    shutil.copy(run / "scene.toml", files)
    assert main(["calibrate", "neuron", str(files), "--draws", "300", "--no-progress"]) == 1
    line = [ln for ln in capsys.readouterr().out.splitlines() if "step_mm:" in ln]
    assert len(line) == 1 and f"step_mm: scan file touch_{wrong:03d}.csv (labelled 0 mm)" in line[0]


def test_labels_that_change_touch_to_touch_are_refused_with_the_plates_they_round_to(run_and_fit, tmp_path, capsys):
    """Each touch labelled with its own measured height (a gauge's reading, 2 um sd about the
    nominal step) made 67 plates, 50 of one scan: the fit ran and failed with 65 problems,
    one line per pair of 'plates'. Now one line names the file and the column, before any
    work, with the grid the labels round to."""
    import numpy as np
    import pandas as pd

    run, _ = run_and_fit
    frame = pd.read_csv(run / "scans.csv")
    ids = frame.scan_id.unique()
    gauge = dict(zip(ids, np.random.default_rng(11).normal(0.0, 0.002, ids.size)))
    frame["step_mm"] = (frame.step_mm + frame.scan_id.map(gauge)).round(4).clip(lower=0)
    csv = tmp_path / "measured" / "scans.csv"
    csv.parent.mkdir()
    frame.to_csv(csv, index=False)
    capsys.readouterr()
    assert main(["calibrate", "neuron", str(csv), "--length-mm", "3", "--out", str(tmp_path / "f"),
                 "--no-progress"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"feeler: error: {csv}: column step_mm: ")
    assert "of them with one scan" in err[0] and "like measured heights" in err[0]
    # the finest grid that puts every touch on its plate: 0.01 mm when no reading crosses a rounding boundary
    assert re.search(r"rounded to the nearest 0\.0[125] mm they form 4 plates \(0, 0\.05, 0\.1, 0\.2 mm\) of 24 "
                     r"scans each\)$", err[0]), err[0]
    assert captured.out == "" and not (tmp_path / "f").exists()


def test_each_label_its_own_and_constant_scans_name_the_file_and_column(run_and_fit, tmp_path, capsys):
    """Every touch labelled with its own measured step (no two alike) said only "one scan on
    each of 96 plates", without the grid they round to; scans whose U_y never changes named an
    argument 'scans', not the file; --noise two-mode with --backend nuts was refused after
    the scans were read (an outside audit)."""
    import numpy as np
    import pandas as pd

    run, _ = run_and_fit
    frame = pd.read_csv(run / "scans.csv")
    ids = frame.scan_id.unique()
    gauge = dict(zip(ids, np.random.default_rng(1).normal(0.0, 0.005, ids.size)))
    cases = {"distinct": frame.assign(step_mm=frame.step_mm + frame.scan_id.map(gauge)),
             "flat": frame.assign(uy_mm=0.0),
             "short": frame[frame.groupby("scan_id").cumcount() < 2],
             "dead": frame.assign(uy_mm=frame.uy_mm.where(frame.step_mm != 0.1, 0.0))}
    for name, table in cases.items():
        (tmp_path / name).mkdir()
        table.to_csv(tmp_path / name / "scans.csv", index=False)
    capsys.readouterr()
    for name, words in (("distinct", "one scan on each of 96 plates: at least 2 scans of a plate (the decoder's noise "
                                     "is the spread of a plate's scans; about 10 per plate pin it down; these change "
                                     "from touch to touch, like measured heights; rounded to the nearest 0.05 mm "
                                     "they form 4 plates (0, 0.05, 0.1, 0.2 mm) of 24 scans each)"),
                        ("flat", "column uy_mm: U_y constant in every scan (all-zero displacements?)"),
                        # two samples a scan named 'argument tau range=(0.5, 0.25)', not the file (an outside audit)
                        ("short", "column t_s: 2 samples a scan: scans of at least 5 samples"),
                        # one plate read as 0 was called noise-free and 'labels swapped' (an outside audit)
                        ("dead", "column uy_mm: U_y 0 in every sample of plate(s) 0.1 mm: scans whose U_y "
                                 "changes over the plate (the sensor read nothing there")):
        csv = tmp_path / name / "scans.csv"
        assert main(["calibrate", "neuron", str(csv), "--length-mm", "3", "--out", str(tmp_path / "f"),
                     "--no-progress"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"feeler: error: {csv}: ") and words in err[0], err
    assert main(["calibrate", "neuron", str(run), "--noise", "two-mode", "--backend", "nuts", "--out",
                 str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("feeler: error: argument --noise='two-mode'") and not any("reading" in e for e in err)


def test_scores_minus_infinity_are_named_not_printed():
    """Shuffled labels left three noise models' leave-one-out scores at -inf, printed as
    'constant -inf, growing -inf, per-plate -inf' (an outside audit)."""
    from feeler.commands._calibrate_neuron import _scores

    text = _scores({"constant": -float("inf"), "two-mode": -39.0, "per-plate": -float("inf")}, 100)
    assert text == "two-mode -0.390, constant, per-plate none: some scan has probability 0 given the others"
    assert "inf" not in _scores({"constant": -12.0}, 10)


def test_a_two_plate_fit_says_its_line_is_untested(run_and_fit, tmp_path, capsys):
    """Two plates pin a and h exactly (their means printed as 0 and 0.1 to 17 digits): the
    fit said ok with nothing to say that no third plate checks the line it reads heights by."""
    import shutil

    import pandas as pd

    run, _ = run_and_fit
    two = tmp_path / "two"
    two.mkdir()
    frame = pd.read_csv(run / "scans.csv")
    frame[frame.step_mm.isin([0.0, 0.1])].to_csv(two / "scans.csv", index=False)
    shutil.copy(run / "scene.toml", two / "scene.toml")
    assert main(["calibrate", "neuron", str(two), "--draws", "300", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "note: two plates: the line z = a·P − h passes through both plates' means exactly" in out
    assert "steps other than 0 and 0.1 mm" in out and "e-1" not in out
    assert main(["calibrate", "neuron", str(run), "--draws", "300", "--no-progress"]) == 0
    assert "two plates" not in capsys.readouterr().out


@pytest.mark.parametrize("backend", [["--backend", "nuts", "--chains", "2", "--draws", "200", "--tune", "100"],
                                     ["--backend", "emcee", "--emcee-steps", "100"]])
def test_the_noise_line_says_why_the_best_score_is_not_the_choice(run_and_fit, capsys, backend):
    """On the shipped four-plates (an outside walk-through, --backend nuts): "decoder noise:
    growing (leave-one-out log score per scan: constant +4.095, growing +4.097, per-plate
    +4.116)", with no word on why per-plate, the best score, was not chosen."""
    run, _ = run_and_fit
    main(["calibrate", "neuron", str(run), *backend, "--no-progress"])
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("decoder noise:"))
    assert line.startswith("decoder noise: growing (leave-one-out log score per scan: "), line
    assert re.search(r"per-plate \+4\.116; per-plate not chosen: its lead over growing, \+0\.0\d\d per scan, is within "
                     r"two standard errors of the difference \(0\.0\d\d per scan\); per-plate is chosen only when it "
                     r"wins by more\)$", line), line


def test_choose_noise_explains_a_top_score_it_passes_over():
    import numpy as np

    from feeler.calib.neuron.model import PeakTable, Plates
    from feeler.calib.neuron.synth import Truth, simulate_peaks
    from feeler.calib.neuron.window import choose_noise

    plates = Plates.of(np.repeat([0.0, 0.05, 0.1, 0.2], 12))
    p = simulate_peaks(plates, Truth(mu=np.array([1.0, 2.0, 3.0, 4.0]), sigma=np.full(4, 0.1)), np.random.default_rng(1))
    table = PeakTable(log_tau=np.array([0.0, 1e-6]), peak=np.repeat(p[:, None], 2, 1))
    one_mode = ("constant", "growing", "per-plate")
    best, scores, _, passed = choose_noise(table, plates, candidates=one_mode, explain=True)
    assert best == "growing" and max(scores, key=scores.get) == "per-plate"
    assert passed["top"] == "per-plate" and passed["chosen"] == "growing" and passed["rule"] == "per-plate"
    assert passed["lead"] == pytest.approx(scores["per-plate"] - scores["growing"]) and passed["two_se"] > passed["lead"]
    assert len(choose_noise(table, plates, candidates=one_mode)) == 3             # as before without explain
