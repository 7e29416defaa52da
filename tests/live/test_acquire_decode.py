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
