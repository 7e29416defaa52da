"""`feeler classify` on unlabelled scans, labelled ones, scans in wrong units, and CSVs
missing what decoding needs."""

import numpy as np
import pytest

from feeler.cli import main


def _run(fit, csv, *extra):
    return main(["classify", str(fit), str(csv), "--n-draws", "40", *extra])


def test_unlabelled_scans_classify_and_labels_add_the_summary(fit_dir, scans_frame, tmp_path, capsys):
    import pandas as pd

    bare = scans_frame[["scan_id", "t_s", "uy_mm"]]
    bare.to_csv(tmp_path / "bare.csv", index=False)
    assert _run(fit_dir, tmp_path / "bare.csv", "--out", str(tmp_path / "a")) == 0
    out = capsys.readouterr().out
    assert "unlabelled scans" in out and "classified as" not in out
    a = pd.read_csv(tmp_path / "a" / "classification.csv")
    assert "step_mm" not in a.columns and not a.flagged.any()
    scans_frame.to_csv(tmp_path / "lab.csv", index=False)
    assert _run(fit_dir, tmp_path / "lab.csv", "--out", str(tmp_path / "b")) == 0
    assert "classified as their labelled plate" in capsys.readouterr().out
    b = pd.read_csv(tmp_path / "b" / "classification.csv")
    p_cols = [c for c in b.columns if c.startswith("p_")]
    np.testing.assert_allclose(a[p_cols].to_numpy(), b[p_cols].to_numpy(), rtol=1e-12)   # labels change nothing
    assert (b.plate_mm == b.step_mm).mean() > 0.5


def test_labels_in_micrometres_are_named_in_the_summary(fit_dir, scans_frame, tmp_path, capsys):
    """Step labels in µm: only the 0 plate matches a trained plate. The accuracy is over
    those scans and says so (it read "100.0 % classified as their labelled plate" over all
    of them), and the summary names the likely unit."""
    um = scans_frame.assign(step_mm=scans_frame.step_mm * 1000)
    um.to_csv(tmp_path / "um.csv", index=False)
    assert _run(fit_dir, tmp_path / "um.csv") == 0
    line = [ln for ln in capsys.readouterr().out.splitlines() if "labelled scans" in ln][0]
    n_zero = int((scans_frame.groupby("scan_id").step_mm.first() == 0).sum())
    assert f"of the {n_zero} labelled with a trained plate classified as it" in line
    assert "labels are probably in um (expected mm)" in line


def test_measured_heights_as_labels_are_named_in_the_summary(fit_dir, scans_frame, tmp_path, capsys):
    """Each scan labelled with its plate's height as a gauge read it (2 um sd about the
    nominal step): only exact plate steps count for the accuracy, and the summary said
    only "labelled with a step the fit has no plate for". It now says they lie near the
    plates and how to count them; labels a quarter of a plate gap away are new steps."""
    ids = scans_frame.scan_id.unique()
    gauge = dict(zip(ids, np.random.default_rng(5).normal(0.0, 0.002, ids.size)))
    measured = scans_frame.assign(step_mm=(scans_frame.step_mm + scans_frame.scan_id.map(gauge)).round(4))
    measured.to_csv(tmp_path / "measured.csv", index=False)
    assert _run(fit_dir, tmp_path / "measured.csv") == 0
    line = [ln for ln in capsys.readouterr().out.splitlines() if "labelled scans" in ln][0]
    assert "like measured heights; label each scan with its plate's step to count it)" in line
    between = scans_frame.assign(step_mm=scans_frame.step_mm.where(scans_frame.step_mm != 0.1, 0.075))
    between.to_csv(tmp_path / "between.csv", index=False)
    assert _run(fit_dir, tmp_path / "between.csv") == 0
    line = [ln for ln in capsys.readouterr().out.splitlines() if "labelled scans" in ln][0]
    assert "labelled with a step the fit has no plate for)" in line and "measured" not in line


def test_scans_of_different_lengths(fit_dir, scans_frame, tmp_path, capsys):
    """A scan cut at half its length is flagged and left out of the accuracy, which says
    so; scans of one or two samples are flags too, never a unit error, and with every
    scan flagged there is no accuracy to report (it gave one, over scans the fit does not
    answer for)."""
    short = scans_frame[~((scans_frame.scan_id == 0) & (scans_frame.t_s > scans_frame.t_s.median()))]
    short.to_csv(tmp_path / "ragged.csv", index=False)
    assert _run(fit_dir, tmp_path / "ragged.csv") == 0
    out = capsys.readouterr().out
    n = scans_frame.scan_id.nunique()
    assert f"{n - 1} labelled scans: " in out and out.rstrip().endswith("; 1 flagged scan(s) left out")
    for k in (1, 2):
        stub = scans_frame[scans_frame.groupby("scan_id").cumcount() < k]
        stub.to_csv(tmp_path / "stub.csv", index=False)
        assert _run(fit_dir, tmp_path / "stub.csv") == 0
        out = capsys.readouterr().out
        assert out.rstrip().endswith(f"{n} labelled scans, all flagged (outside the fit's training envelope: see the "
                                     "flags): no accuracy to report") and "probably in" not in out


# U_y in cm (an outside audit): its largest rise reads like a small step, inside the training
# range; the scans were read as plate 0 at p = 0.999, unflagged. Its noise is 10x quieter too.
@pytest.mark.parametrize("column, factor, words", [("t_s", 1000.0, "ms"), ("uy_mm", 1000.0, "um"),
                                                   ("uy_mm", 0.1, "U_y probably in cm or inches")])
def test_wrong_units_are_one_line_errors(fit_dir, scans_frame, tmp_path, capsys, column, factor, words):
    bad = scans_frame.copy()
    bad[column] = bad[column] * factor
    bad.to_csv(tmp_path / "bad.csv", index=False)
    assert _run(fit_dir, tmp_path / "bad.csv") == 2
    err = capsys.readouterr().err
    said = [ln for ln in err.splitlines() if ln.startswith("feeler: ")]       # beside the first status line
    assert len(said) == 1 and words in said[0] and "bad.csv" in said[0] and "Traceback" not in err
    assert ("scan_id" in said[0]) == (factor > 1)                   # the batch's quiet noise names no one scan


def test_missing_columns_and_bad_values(fit_dir, scans_frame, tmp_path, capsys):
    scans_frame[["scan_id", "t_s"]].to_csv(tmp_path / "no_uy.csv", index=False)
    assert _run(fit_dir, tmp_path / "no_uy.csv") == 2
    err = capsys.readouterr().err
    assert "missing column(s) uy_mm" in err and "required: scan_id, t_s, uy_mm" in err
    scans_frame.rename(columns={"t_s": "t [ms]", "uy_mm": "Uy [mm]"}).to_csv(tmp_path / "units.csv", index=False)
    assert _run(fit_dir, tmp_path / "units.csv") == 2
    assert ("the header has 'Uy [mm]': rename it uy_mm; 't [ms]' is in ms: t_s is in s (convert it)"
            in capsys.readouterr().err)
    back = scans_frame.copy()
    back.loc[3, "t_s"] = back.loc[1, "t_s"]
    back.to_csv(tmp_path / "back.csv", index=False)
    assert _run(fit_dir, tmp_path / "back.csv") == 2
    assert "not strictly increasing" in capsys.readouterr().err
    assert _run(fit_dir, tmp_path / "none.csv") == 2


def test_many_flagged_scans_name_ten_and_count_the_rest(fit_dir, scans_frame, tmp_path, capsys):
    """Every scan sampled half as often as the training scans: ten flag lines, then one line counting the
    rest and saying where all of them are (it printed one line per scan, however many)."""
    import pandas as pd

    n = scans_frame.scan_id.nunique()
    copies = -(-14 // n)
    slow = pd.concat([scans_frame.assign(scan_id=scans_frame.scan_id + 1000 * k, t_s=scans_frame.t_s * 2)
                      for k in range(copies)])
    slow.to_csv(tmp_path / "slow.csv", index=False)
    assert _run(fit_dir, tmp_path / "slow.csv", "--out", str(tmp_path / "c")) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sum(" flagged: sampling period" in ln for ln in lines) == 10
    total = n * copies
    assert (f"... {total - 10} more flagged scans ({total} of {total} in all); every scan's reason is in the flag "
            f"column of {tmp_path / 'c' / 'classification.csv'}") in lines
    assert pd.read_csv(tmp_path / "c" / "classification.csv").flagged.sum() == total


def test_a_directory_without_scans_says_so_and_what_it_holds(fit_dir, tmp_path, capsys):
    """It named samples.csv only, the file of a run in progress; a fit handed as SCANS is named as a fit."""
    (tmp_path / "empty").mkdir()
    assert _run(fit_dir, tmp_path / "empty") == 2
    assert _run(fit_dir, fit_dir) == 2
    said = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler: ")]
    nothing = ("holds no scans.csv (nor the samples.csv of a run in progress, nor CSV files of one scan each with "
               "columns t_s, uy_mm)")
    assert said == [f"feeler: error: {tmp_path / 'empty'}: {nothing}",
                    f"feeler: error: {fit_dir}: {nothing}; "
                    f"{fit_dir} holds a fit (posterior.nc): fits are read by `feeler classify`, `discriminate`, "
                    "`decode` and `report`"]


def test_a_directory_of_one_file_per_scan_classifies_naming_each_file(fit_dir, scans_frame, tmp_path, capsys):
    import pandas as pd

    lab = tmp_path / "lab"
    lab.mkdir()
    ids = sorted(scans_frame.scan_id.unique())
    for k, sid in enumerate(ids):
        scans_frame[scans_frame.scan_id == sid].drop(columns="scan_id").to_csv(lab / f"touch{k + 1}.csv", index=False)
    scans_frame.to_csv(tmp_path / "all.csv", index=False)
    assert _run(fit_dir, tmp_path / "all.csv", "--out", str(tmp_path / "a")) == 0
    assert _run(fit_dir, lab, "--out", str(tmp_path / "b")) == 0
    capsys.readouterr()
    a, b = (pd.read_csv(tmp_path / d / "classification.csv") for d in ("a", "b"))
    assert b.file.tolist() == [f"touch{k + 1}.csv" for k in range(len(ids))]       # touch2 before touch10
    p_cols = [c for c in a.columns if c.startswith("p_")] + ["height_mm", "lo90_mm", "hi90_mm", "step_mm"]
    np.testing.assert_allclose(b[p_cols].to_numpy(), a[p_cols].to_numpy(), rtol=1e-12)
    # one file's U_y in um: the error names that file, not an internal scan_id (an outside audit)
    eighth = pd.read_csv(lab / "touch8.csv")
    eighth.assign(uy_mm=eighth.uy_mm * 1e3).to_csv(lab / "touch8.csv", index=False)
    assert _run(fit_dir, lab, "--out", str(tmp_path / "c")) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"feeler: error: {lab}: scan file touch8.csv: response ") and "probably in um" in err[-1]


def test_scans_named_by_the_lab_keep_their_names(fit_dir, scans_frame, tmp_path, capsys):
    """scan_id 'S1-T01' ... (names, not numbers): classified as the numbered file, each row
    under the file's own name (it was 'column scan_id: missing or non-numeric value')."""
    import pandas as pd

    named = scans_frame.assign(scan_id=[f"S1-T{int(v):02d}" for v in scans_frame.scan_id])
    named.to_csv(tmp_path / "named.csv", index=False)
    scans_frame.to_csv(tmp_path / "all.csv", index=False)
    assert _run(fit_dir, tmp_path / "all.csv", "--out", str(tmp_path / "a")) == 0
    assert _run(fit_dir, tmp_path / "named.csv", "--out", str(tmp_path / "b")) == 0
    assert "classified as their labelled plate" in capsys.readouterr().out
    a, b = (pd.read_csv(tmp_path / d / "classification.csv") for d in ("a", "b"))
    assert b.scan_id.tolist() == [f"S1-T{int(v):02d}" for v in a.scan_id]
    cols = [c for c in a.columns if c.startswith("p_")] + ["height_mm", "lo90_mm", "hi90_mm", "step_mm"]
    np.testing.assert_allclose(b[cols].to_numpy(), a[cols].to_numpy(), rtol=1e-12)


def test_a_batch_noisier_than_the_training_scans_is_flagged_whole(fit_dir, scans_frame, tmp_path, capsys):
    """The fit's own scans with 2 um more read-out noise: each scan's noise is within the
    training range often enough, but the batch's median is about twice the training
    scans', so every scan is flagged with that reason and no accuracy is claimed. They
    were decoded as if from the training set-up (1.5x the noise: 50 % of labels inside
    their 90 % intervals)."""
    import pandas as pd

    noisy = scans_frame.assign(uy_mm=scans_frame.uy_mm + 0.002 * np.random.default_rng(3).standard_normal(
        len(scans_frame)))
    noisy.to_csv(tmp_path / "noisy.csv", index=False)
    assert _run(fit_dir, tmp_path / "noisy.csv", "--out", str(tmp_path / "n")) == 0
    out = capsys.readouterr().out
    assert "all flagged" in out and "no accuracy to report" in out
    table = pd.read_csv(tmp_path / "n" / "classification.csv")
    assert table.flagged.all()
    assert table.flag.str.contains(r"these 12 scans' read-out noise \(median [\d.]+ um\) is [\d.]+× the training "
                                   r"scans'").all()
    scans_frame.to_csv(tmp_path / "same.csv", index=False)
    assert _run(fit_dir, tmp_path / "same.csv", "--out", str(tmp_path / "s")) == 0
    assert not pd.read_csv(tmp_path / "s" / "classification.csv").flagged.any()


def test_long_work_says_how_far_it_is_and_no_progress_silences_it(fit_dir, scans_frame, tmp_path, capsys,
                                                                    monkeypatch):
    """Off a terminal: a line per stage and, over several blocks of scans, a line per block
    with the time left (20 000 scans decode for about a minute, which said nothing)."""
    import feeler.calib.neuron.classify as cl

    monkeypatch.setattr(cl, "BLOCK", 10)
    scans_frame.to_csv(tmp_path / "lab.csv", index=False)
    n = scans_frame.scan_id.nunique()
    blocks = -(-n // 10)
    assert _run(fit_dir, tmp_path / "lab.csv") == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("feeler classify: classifying the scans")         # within a second, while loading
    assert err[1:3] == [f"reading {tmp_path / 'lab.csv'} ...", f"decoding {n} scans with 40 posterior draws ..."]
    done = [ln for ln in err if ln.startswith(f"decoding {n} scans: ")]
    assert len(done) == blocks and done[0].startswith(f"decoding {n} scans: 1/{blocks} done")
    assert _run(fit_dir, tmp_path / "lab.csv", "--no-progress") == 0
    assert len(capsys.readouterr().err.splitlines()) <= 1             # at most the line said while loading


def test_labels_that_contradict_the_fit_are_a_warning(fit_dir, fresh_frame, tmp_path, capsys):
    """Fresh scans of the training scene, labelled right: no warning. The same scans with
    the labels of two plates exchanged: the summary's figures alone said so (and every
    scan is unflagged); now a warning names both claims that fail."""
    fresh_frame.to_csv(tmp_path / "right.csv", index=False)
    assert _run(fit_dir, tmp_path / "right.csv") == 0
    out = capsys.readouterr().out
    assert f"{fresh_frame.scan_id.nunique()} labelled scans" in out and "warning" not in out
    swapped = fresh_frame.assign(step_mm=fresh_frame.step_mm.replace({0.05: 0.1, 0.1: 0.05}))
    swapped.to_csv(tmp_path / "swapped.csv", index=False)
    assert _run(fit_dir, tmp_path / "swapped.csv") == 0
    warnings = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("warning: ")]
    assert len(warnings) == 2, warnings
    assert "labels inside their 90 % interval" in warnings[0] and "over-confident" in warnings[1]
    assert "labels that are wrong" in warnings[1]


def test_more_draws_than_the_fit_has_is_a_note_with_the_true_count(fit_dir, scans_frame, tmp_path, capsys):
    """--n-draws 100000 on a fit of 4000 draws ran silently (an outside audit)."""
    import xarray as xr

    with xr.open_datatree(fit_dir / "posterior.nc", engine="h5netcdf") as tree:
        have = int(tree["posterior"].sizes["chain"] * tree["posterior"].sizes["draw"])
    scans_frame.to_csv(tmp_path / "lab.csv", index=False)
    assert main(["classify", str(fit_dir), str(tmp_path / "lab.csv"), "--n-draws", str(10 * have)]) == 0
    out = capsys.readouterr().out
    assert f"note: --n-draws {10 * have} is more than the fit's {have} posterior draws: all {have} are used" in out
    assert main(["classify", str(fit_dir), str(tmp_path / "lab.csv"), "--n-draws", "40"]) == 0
    assert "note: --n-draws" not in capsys.readouterr().out


def test_scans_with_u_y_negated_are_flagged_by_classify_and_decode(fit_dir, scans_frame, tmp_path, capsys):
    """U_y with its sign flipped reads as its plate (the window sums follow how much U_y
    changes): classify flags every riser's scan as falling, and decode decides none of them."""
    import pandas as pd

    scans_frame.assign(uy_mm=-scans_frame.uy_mm).to_csv(tmp_path / "negated.csv", index=False)
    assert _run(fit_dir, tmp_path / "negated.csv", "--out", str(tmp_path / "c")) == 0
    table = pd.read_csv(tmp_path / "c" / "classification.csv")
    riser = table.step_mm > 0
    assert table.flag[riser].str.contains("U_y falls by").all() and not table.flagged[~riser].any()
    assert main(["decode", str(fit_dir), str(tmp_path / "negated.csv"), "--out", str(tmp_path / "d"), "--n-draws", "40",
                 "--no-live"]) == 0
    decided = pd.read_csv(tmp_path / "d" / "decisions.csv")
    assert decided.decided_mm[riser.to_numpy()].isna().all()
    capsys.readouterr()


def test_a_batch_a_fifth_off_every_plate_is_noted(small_fit, fit_dir, tmp_path, capsys):
    """U_y x 0.7 (a gain inside the response check's x2): some scans read between plates and
    are flagged, and the others are read as usual, some wrong at p >= 0.9 (an outside audit).
    When a fifth or more of a batch of 20 or more lies off every plate, classify says the
    batch itself is in doubt, and so does decode of the same scans; the scans as they are,
    neither."""
    import pandas as pd

    data, res = small_fit
    length = float(res.posterior["posterior"].attrs["length_mm"])
    n, m = data.strain.shape
    frame = pd.DataFrame({"scan_id": np.repeat(np.arange(n), m), "t_s": np.tile(data.t_s, n),
                          "uy_mm": (data.strain * length).ravel()})
    frame.to_csv(tmp_path / "as_is.csv", index=False)
    frame.assign(uy_mm=frame.uy_mm * 0.7).to_csv(tmp_path / "gain.csv", index=False)
    assert _run(fit_dir, tmp_path / "as_is.csv") == 0
    assert "sds from every trained plate: a batch on another scale" not in capsys.readouterr().out
    assert _run(fit_dir, tmp_path / "gain.csv", "--out", str(tmp_path / "g")) == 0
    said = [ln for ln in capsys.readouterr().out.splitlines() if "sds from every trained plate: a batch" in ln]
    off = int(pd.read_csv(tmp_path / "g" / "classification.csv").flag.str.contains("sds from the nearest").sum())
    assert off >= 0.2 * n and said == [f"note: {off} of {n} scans read more than 5 sds from every trained plate: a "
                                       "batch on another scale (a gain, a unit or a set-up unlike the training's) or "
                                       "of steps the fit was not trained on, so the other scans' probabilities may "
                                       "not hold either"]
    for name, noted in (("as_is", False), ("gain", True)):
        assert main(["decode", str(fit_dir), str(tmp_path / f"{name}.csv"), "--n-draws", "40", "--no-progress",
                     "--out", str(tmp_path / f"d_{name}")]) == 0
        said = [ln for ln in capsys.readouterr().out.splitlines() if "sds from every trained plate: a batch" in ln]
        flags = pd.read_csv(tmp_path / f"d_{name}" / "decisions.csv", keep_default_na=False).flag
        off = int(flags.str.contains("sds from the nearest").sum())
        assert said == ([f"note: {off} of {n} scans read more than 5 sds from every trained plate: a batch on "
                         "another scale (a gain, a unit or a set-up unlike the training's) or of steps the fit was "
                         "not trained on, so the other scans' probabilities and decisions may not hold either"]
                        if noted else []), (name, off)


def test_a_unit_flag_against_a_fit_whose_own_verdict_names_its_units_blames_the_fit():
    """A fit trained on U_y in um, used with --accept-failed on scans in mm: the scans read
    1e-3 times its training scans', and classify said 'U_y probably in m' of the right file."""
    from feeler.calib.neuron.live.table import unit_mistake
    from feeler.errors import DataFileError

    flags = [[], ["response 0.00161× the smallest training scan's: U_y probably in m (expected mm)"]]
    own = "a: the scans' rise in U_y is 975 times the labelled steps (expected about 1, both in mm): U_y probably in um"
    with pytest.raises(DataFileError) as plain:
        unit_mistake("new.csv", ["scan_id 0", "scan_id 1"], flags)
    assert "U_y probably in m (expected mm); the scan CSV takes t_s in s" in str(plain.value)
    with pytest.raises(DataFileError) as blamed:
        unit_mistake("new.csv", ["scan_id 0", "scan_id 1"], flags, ["tau_s: something else", own])
    text = str(blamed.value)
    assert "scan_id 1: response 0.00161× the smallest training scan's: these scans and the fit's training scans" in text
    assert f"the fit's own verdict names its training scans' units ({own}); refit with them in mm" in text
    assert "probably in m (" not in text
    unit_mistake("new.csv", ["scan_id 0"], [["speed 2x the fit's"]], [own])       # no unit flag: nothing raised


def test_copies_of_one_scan_are_named_in_a_note(fit_dir, scans_frame, tmp_path, capsys):
    """Every scan's U_y replaced by scan 0's (its times kept): each copy was classified at the
    same p without a word. Real scans give no such note."""
    frame = scans_frame[["scan_id", "t_s", "uy_mm"]].copy()
    first = frame[frame.scan_id == frame.scan_id.iloc[0]].uy_mm.to_numpy()
    frame["uy_mm"] = np.concatenate([first[: (frame.scan_id == s).sum()] for s in frame.scan_id.unique()])
    frame.to_csv(tmp_path / "copies.csv", index=False)
    assert _run(fit_dir, tmp_path / "copies.csv") == 0
    n = frame.scan_id.nunique()
    first_id, second_id = frame.scan_id.unique()[:2]
    assert (f"note: {n - 1} of {n} scans repeat an earlier scan's U_y at every sample (e.g. scan_id {second_id} = "
            f"scan_id {first_id}): a scan copied under new ids") in capsys.readouterr().out
    scans_frame[["scan_id", "t_s", "uy_mm"]].to_csv(tmp_path / "real.csv", index=False)
    assert _run(fit_dir, tmp_path / "real.csv") == 0
    assert "repeat an earlier scan" not in capsys.readouterr().out
