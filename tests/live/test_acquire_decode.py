"""`feeler acquire --emulate --decode FIT`: the decisions written while acquiring equal
`feeler decode` and `feeler classify` of the same run afterwards."""

from pathlib import Path

import numpy as np
import pandas as pd

from feeler.cli import main

TINY = Path(__file__).parents[1] / "hardware" / "data" / "tiny-plan.toml"


def test_emulated_campaign_decodes_like_offline(fit_dir, tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["acquire", "--emulate", "--plan", str(TINY), "--out", str(run), "--no-progress",
                 "--decode", str(fit_dir)]) == 0
    capsys.readouterr()
    live = pd.read_csv(run / "decisions.csv")
    assert sorted(live.scan_id) == sorted(pd.read_csv(run / "scans.csv").scan_id.unique())
    assert live.flagged.all()          # the tiny plan's 0.1 s, 4-sample scans are not the fit's: said so
    assert main(["decode", str(fit_dir), str(run), "--out", str(tmp_path / "off"), "--no-live"]) == 0
    off = pd.read_csv(tmp_path / "off" / "decisions.csv")
    pd.testing.assert_frame_equal(live, off, rtol=1e-12)
    assert main(["classify", str(fit_dir), str(run), "--out", str(tmp_path / "c")]) == 0
    cls = pd.read_csv(tmp_path / "c" / "classification.csv")
    cols = [c for c in live.columns if c.startswith("p_") and c.endswith("mm")]
    np.testing.assert_allclose(live[cols].to_numpy(), cls[cols].to_numpy(), rtol=1e-9, atol=1e-300)


def test_decode_with_a_missing_fit_fails_before_anything_moves(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["acquire", "--emulate", "--plan", str(TINY), "--out", str(run), "--no-progress",
                 "--decode", str(tmp_path / "no-fit")]) == 2
    assert "no-fit" in capsys.readouterr().err
    assert not (run / "samples.csv").exists()


def test_a_failed_fit_is_refused_and_the_option_it_names_exists(fit_dir, tmp_path, capsys):
    """A --decode fit that failed its diagnostics is refused before anything moves, with
    'pass --accept-failed to use it anyway', an option acquire did not have (argparse then
    said 'unrecognized arguments'); with it the run decodes."""
    import json
    import shutil

    failed = tmp_path / "failed-fit"
    shutil.copytree(fit_dir, failed)
    (failed / "verdict.json").write_text(json.dumps({"ok": False, "problems": ["tau_s: not pinned"]}))
    run = tmp_path / "run"
    argv = ["acquire", "--emulate", "--plan", str(TINY), "--out", str(run), "--no-progress", "--decode", str(failed)]
    assert main(argv) != 0
    err = capsys.readouterr().err
    assert "pass --accept-failed to use it anyway" in err and not (run / "samples.csv").exists()
    assert main([*argv, "--accept-failed"]) == 0
    assert (run / "decisions.csv").is_file()


def test_acquire_decode_flags_the_batch_as_classify_does(fit_dir, scans_frame, tmp_path, capsys):
    """`acquire --decode` (its campaign observer, fed as a campaign feeds it) judges the
    batch's read-out noise as classify does, as soon as its scans tell: scans with 2 um
    more noise end flagged with classify's reason, the scans after the 5th are not decided,
    and it says so at the end. It decided such scans unflagged (an outside walk-through:
    emulated scans, far quieter than the shipped four-plates fit's, decided at p 0.999)."""
    from feeler.calib.neuron.live.observer import decode_observer

    noisy = scans_frame.assign(uy_mm=scans_frame.uy_mm + 0.002 * np.random.default_rng(3).standard_normal(
        len(scans_frame)))
    run = tmp_path / "run"
    run.mkdir()
    observer = decode_observer(fit_dir, run, n_draws=40)
    groups = list(noisy.groupby("scan_id", sort=False))
    observer.started(len(groups), 0, 41)
    for sid, rows in groups:
        observer.event("scan_start", {"scan_id": int(sid), "attempt": 0})
        for row in rows.assign(attempt=0).to_dict("records"):
            observer.sample(row)
        observer.event("scan_done", {"scan_id": int(sid), "n_samples": len(rows)})
    observer.finished({})
    live = pd.read_csv(run / "decisions.csv")
    assert len(live) == len(groups) and live.flagged.all() and live.decided_mm[5:].isna().all()
    noisy.to_csv(tmp_path / "noisy.csv", index=False)
    assert main(["classify", str(fit_dir), str(tmp_path / "noisy.csv"), "--n-draws", "40",
                 "--out", str(tmp_path / "c")]) == 0
    cls = pd.read_csv(tmp_path / "c" / "classification.csv")
    assert live.flag.tolist() == cls.flag.tolist()
    assert f"note: every scan is flagged: these {len(groups)} scans' read-out noise" in capsys.readouterr().out


def test_resume_with_decode_decodes_the_scans_acquired_before(fit_dir, tmp_path, capsys):
    """A run stopped after 2 of 4 scans, acquired without --decode, then resumed with
    --decode: decisions.csv held only the 2 scans of the resumed part (an outside
    walk-through), while --help says every scan is decoded "as `feeler decode`". Now the
    scans done before are decoded first: decisions.csv equals `feeler decode` of the run,
    and one line says so."""
    run = tmp_path / "run"
    argv = ["acquire", "--emulate", "--plan", str(TINY), "--out", str(run)]
    assert main(argv + ["--no-progress", "--fault", "vanish:reply=ok,nth=17"]) == 1   # ok 17: scan 2's first move
    assert pd.read_csv(run / "scans.csv").scan_id.unique().tolist() == [0, 1]
    capsys.readouterr()
    assert main(argv + ["--resume", "--decode", str(fit_dir)]) == 0
    err = capsys.readouterr().err
    assert f"feeler acquire: decoded the 2 scans acquired before this resume into {run / 'decisions.csv'}" in err
    live = pd.read_csv(run / "decisions.csv")
    assert live.scan_id.tolist() == [0, 1, 2, 3]
    assert main(["decode", str(fit_dir), str(run), "--out", str(tmp_path / "off"), "--no-live"]) == 0
    pd.testing.assert_frame_equal(live, pd.read_csv(tmp_path / "off" / "decisions.csv"), rtol=1e-12)


def test_decode_with_no_progress_prints_no_decision_lines(fit_dir, tmp_path, capsys):
    """`acquire --decode --no-progress` printed a line per decision (and per flagged scan)
    on stderr, where `decode --no-progress` prints none: now neither does."""
    run = tmp_path / "run"
    assert main(["acquire", "--emulate", "--plan", str(TINY), "--out", str(run), "--no-progress",
                 "--decode", str(fit_dir)]) == 0
    err = capsys.readouterr().err
    assert not [ln for ln in err.splitlines() if ln.startswith("scan ")], err
    assert len(pd.read_csv(run / "decisions.csv")) == 4
    assert main(["acquire", "--emulate", "--plan", str(TINY), "--out", str(run), "--force",
                 "--decode", str(fit_dir)]) == 0
    assert [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("scan ")]   # without it: the lines
