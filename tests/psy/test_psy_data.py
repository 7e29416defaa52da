"""The trial-table reader (every layout and validation branch), the scene and the simulator."""
import json
from pathlib import Path

import numpy as np
import pytest

from feeler.errors import DataFileError, OverwriteError, SceneError
from feeler.psydata import KEY_COLUMNS, NAFC_COLUMNS, TRIAL_COLUMNS, read_trials, write_trials
from feeler.scene import load_scene
from feeler.simulate.psychophysics import simulate_psychophysics

SCENE = Path(__file__).parents[2] / "datasets-synthetic" / "psychophysics-2afc.toml"
HEADER = ",".join(TRIAL_COLUMNS)


def _csv(tmp_path, *rows, header=HEADER):
    path = tmp_path / "t.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def test_reads_comments_zero_trials_and_extreme_cells(tmp_path):
    path = _csv(tmp_path, "A,10,20,7.6,20,0,0", "A,10,20,12.4,20,15,15", "B,10,40,7.6,20,15,15")
    path.write_text("# synthetic\n" + path.read_text())
    df = read_trials(path)
    assert list(df.columns) == list(TRIAL_COLUMNS) and len(df) == 3
    assert df["n_trials"].tolist() == [0, 15, 15] and df["n_trials"].dtype == np.int64
    assert df["subject"].tolist() == ["A", "A", "B"]


def test_extra_columns_are_ignored_and_order_is_free(tmp_path):
    cols = list(reversed(TRIAL_COLUMNS)) + ["note"]
    path = _csv(tmp_path, "3,5,20,8,20,10,S1,x", header=",".join(cols))
    df = read_trials(path)
    assert df.loc[0, "subject"] == "S1" and df.loc[0, "comparison_um"] == 8.0


@pytest.mark.parametrize("rows, header, match", [
    (("A,10,20,7.6,20,10,3",), "subject,standard_um,comparison_um,n_trials,n_comparison_higher",
     "missing column.*standard_speed_mm_s"),
    (("A,10,20,7.6,20,10",), ",".join(KEY_COLUMNS) + ",n_trials", "missing column.*n_comparison_higher or n_correct"),
    (("A,10,20,7.6,20",), ",".join(KEY_COLUMNS), "missing column.*one row per trial"),
    (("A,10,20,7.6,20,10,3",), "Subject,standard [um],standard_speed_mm_s,comparison (µm),comparison_speed_mm_s,"
     "n_trials,n_comparison_higher", "the header has 'Subject', 'standard \\[um\\]', 'comparison \\(µm\\)': rename them "
     "subject, standard_um, comparison_um"),
    (("A,10,20,7.6,20,0.3",), ",".join(KEY_COLUMNS) + ",p_higher", "missing column.*'p_higher' looks like a "
     "proportion: the fit needs counts, n_comparison_higher \\(or n_correct\\) = proportion × n_trials"),
    (("A,10,20,7.6,20,10,30",), ",".join(KEY_COLUMNS) + ",n_trials,percent correct", "'percent correct' looks "
     "like a proportion"),
    (("A,10,20,7.6,20,10,3,3",), HEADER + ",n_correct", "both n_comparison_higher and n_correct"),
    (("A,10,20,7.6,20,1,0",), ",".join(KEY_COLUMNS) + ",correct,comparison_higher", "both comparison_higher and correct"),
    (("A,10,20,7.6,20,maybe",), ",".join(KEY_COLUMNS) + ",correct", "line 2, column correct: 'maybe' must be 1 or 0"),
    (("A,10,20,7.6,20,2",), ",".join(KEY_COLUMNS) + ",comparison_higher", "column comparison_higher: '2' must be 1 or 0"),
    (("A,0,20,7.6,20,10,3",), HEADER, "column standard_um: 0.0 must be finite and > 0"),
    (("A,-1,20,7.6,20,10,3",), ",".join(NAFC_COLUMNS), "column standard_um: -1.0 must be finite and >= 0"),
    (("A,10,20,7.6,20,0,0", "B,10,20,8.4,20,0,0"), HEADER, "no trials: every row has n_trials = 0"),
    (("A,10,20,7.6,20,ten,3",), HEADER, "column n_trials: 'ten' is not a number"),
    (("A,10,20,7.6,20,-1,0",), HEADER, "line 2, column n_trials.*whole number"),
    (("A,10,20,7.6,20,10,-2",), HEADER, "line 2, column n_comparison_higher.*whole number"),
    (("A,10,20,7.6,20,10,11",), HEADER, "line 2, column n_comparison_higher: 11 > n_trials 10"),
    (("A,10,20,7.6,20,10,3", "A,ten,20,7.6,20,10,3"), HEADER, "line 3, column standard_um: 'ten' is not a number"),
    (("A,10,20,7.6,20,2.5,1",), HEADER, "column n_trials.*whole number"),
    (("A,10,0,7.6,20,10,1",), HEADER, "column standard_speed_mm_s.*> 0"),
    (("A,10,20,nan,20,10,1",), HEADER, "column comparison_um.*finite"),
    (("A,10,20,1e300,20,10,1",), HEADER, r"line 2, column comparison_um: 1e\+300 must be at most 1e\+12"),
    ((",10,20,7.6,20,10,1",), HEADER, "column subject: empty"),
    (("A,10,20,7.6,20,10",), HEADER, "line 2: 6 fields"),
    ((), HEADER, "no data rows"),
])
def test_each_validation_branch_is_one_line_error(tmp_path, rows, header, match):
    path = _csv(tmp_path, *rows, header=header)
    with pytest.raises(DataFileError, match=match) as info:
        read_trials(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)


def test_trial_by_trial_file_is_aggregated_like_its_counts(tmp_path):
    trials = ["A,10,20,7.6,20,1", "A,10,20,7.6,20,no", "B,10,40,8.4,20,TRUE", "A,10,20,7.6,20,0",
              "A,10,20,12.4,20,yes", "B,10,40,8.4,20,false"]
    path = _csv(tmp_path, *trials, header=",".join(KEY_COLUMNS) + ",comparison_higher")
    df = read_trials(path)
    assert list(df.columns) == list(TRIAL_COLUMNS) and df.attrs["trial_rows"] == 6
    assert df[["subject", "comparison_um", "n_trials", "n_comparison_higher"]].values.tolist() == [
        ["A", 7.6, 3, 1], ["B", 8.4, 2, 1], ["A", 12.4, 1, 1]]
    counts = _csv(tmp_path, "A,10,20,7.6,20,3,1", "B,10,40,8.4,20,2,1", "A,10,20,12.4,20,1,1")
    assert read_trials(counts).equals(df) and read_trials(counts).attrs["trial_rows"] == 0


def test_nafc_tables_allow_a_flat_standard(tmp_path):
    path = _csv(tmp_path, "A,0,20,1.5,20,40,30", header=",".join(NAFC_COLUMNS))
    df = read_trials(path)
    assert list(df.columns) == list(NAFC_COLUMNS) and df.loc[0, "standard_um"] == 0.0
    write_trials(tmp_path / "o.csv", df)
    assert read_trials(tmp_path / "o.csv").equals(df)
    trial = _csv(tmp_path, "A,0,20,1.5,20,1", "A,0,20,1.5,20,0", header=",".join(KEY_COLUMNS) + ",correct")
    assert read_trials(trial)[["n_trials", "n_correct"]].values.tolist() == [[2, 1]]


def test_missing_empty_and_undecodable_files(tmp_path):
    with pytest.raises(DataFileError, match="no such file"):
        read_trials(tmp_path / "absent.csv")
    (tmp_path / "e.csv").write_text("# only a comment\n")
    with pytest.raises(DataFileError, match="no header"):
        read_trials(tmp_path / "e.csv")
    (tmp_path / "b.csv").write_bytes(b"\xff\xfe\x00ba")           # UTF-16 by its mark, cut mid-character
    with pytest.raises(DataFileError, match="cannot read"):
        read_trials(tmp_path / "b.csv")


def test_scene_loads_and_respects_published_ranges():
    scene = load_scene(SCENE)
    assert "synthetic" in scene.scene.description.lower()
    by_speed = {c.standard_speed_mm_s: c for c in scene.conditions}
    assert by_speed[40.0].dt_um > by_speed[20.0].dt_um and by_speed[40.0].pse_um > by_speed[20.0].pse_um
    assert all(0.95 <= c.dt_um <= 2.0 for c in scene.conditions)


@pytest.mark.parametrize("old, new, key", [
    ('description = "Synthetic', 'description = "Real', "scene.description"),
    ("[7.6, 8.4,", "[8.4, 7.6,", "design.comparisons_um"),
    ("dt_range_um = [0.95, 2.0]", "dt_range_um = [2.0, 0.95]", "subjects.dt_range_um"),
    ("lapse_range = [0.0, 0.06]", "lapse_range = [0.06, 0.0]", "subjects.lapse_range"),
    ("dt_um = 1.6", "dt_um = 2.5", "conditions[1].dt_um"),
    ("standard_speed_mm_s = 40.0", "standard_speed_mm_s = 20.0", "conditions[1]"),
])
def test_scene_cross_field_rules(tmp_path, old, new, key):
    text = SCENE.read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(SceneError) as info:
        load_scene(bad)
    assert info.value.key == key


def test_simulator_writes_labelled_reproducible_data(tmp_path):
    scene = load_scene(SCENE)
    paths = simulate_psychophysics(scene, tmp_path / "a")
    assert paths["trials"].read_text().startswith("# SYNTHETIC")
    truth = json.loads(paths["truth"].read_text())
    assert truth["synthetic"] is True and len(truth["subjects"]) == 6 * 2
    assert all(0.95 <= s["dt_um"] <= 2.0 for s in truth["subjects"])
    df = read_trials(paths["trials"])
    assert len(df) == 6 * 2 * 7 and df["subject"].nunique() == 6
    again = simulate_psychophysics(scene, tmp_path / "b")
    assert again["trials"].read_text() == paths["trials"].read_text()
    with pytest.raises(OverwriteError):
        simulate_psychophysics(scene, tmp_path / "a")
    simulate_psychophysics(scene, tmp_path / "a", force=True)


def test_simulated_proportions_follow_the_truth(tmp_path):
    # many trials: the observed proportion is within 4 binomial sd of the true P
    from dataclasses import replace
    from feeler.models.psychometric import p_higher
    scene = load_scene(SCENE)
    scene = replace(scene, design=replace(scene.design, n_trials=4000))
    paths = simulate_psychophysics(scene, tmp_path)
    df = read_trials(paths["trials"])
    truth = json.loads(paths["truth"].read_text())["subjects"]
    for t in truth:
        sel = df[(df.subject == t["subject"]) & (df.standard_speed_mm_s == t["standard_speed_mm_s"])]
        p = p_higher(sel.comparison_um.to_numpy(), t["pse_um"], t["sigma_um"], t["lapse"])
        sd = np.sqrt(p * (1 - p) / 4000)
        assert np.all(np.abs(sel.n_comparison_higher / 4000 - p) <= 4 * sd + 1e-9)


def test_beta_binomial_option_is_overdispersed(tmp_path):
    from dataclasses import replace
    scene = load_scene(SCENE)
    design = replace(scene.design, n_trials=200, n_subjects=40)
    plain = replace(scene, design=design)
    over = replace(plain, subjects=replace(scene.subjects, overdispersion_phi=5.0))
    var = []
    for i, sc in enumerate((plain, over)):
        df = read_trials(simulate_psychophysics(sc, tmp_path / str(i))["trials"])
        mid = df[(df.comparison_um == 10.0) & (df.standard_speed_mm_s == 20.0)]
        var.append(np.var(mid.n_comparison_higher / 200))
    assert var[1] > 4 * var[0]


def test_write_trials_round_trip(tmp_path):
    df = read_trials(_csv(tmp_path, "A,10,20,7.6,20,10,3"))
    write_trials(tmp_path / "o.csv", df, comment="synthetic\nline two")
    assert (tmp_path / "o.csv").read_text().startswith("# synthetic\n# line two\n")
    assert read_trials(tmp_path / "o.csv").equals(df)


def test_a_decimal_comma_spreadsheet_export_reads_as_the_comma_file(tmp_path):
    """';' between columns, ',' as the decimal mark, a byte order mark before the first
    comment (what a spreadsheet in a German or French locale writes): the same table."""
    rows = ["A,10,20,7.6,20,20,3", "A,10,20,12.4,20,20,17", "Smith J,10,40,9.8,40,20,9"]
    plain = read_trials(_csv(tmp_path, *rows))
    eu = tmp_path / "eu.csv"
    eu.write_text("# synthetic, two subjects\n" + "\n".join(
        [";".join(TRIAL_COLUMNS)] + [";".join(f.replace(".", ",") for f in r.split(",")) for r in rows]) + "\n",
        encoding="utf-8-sig")
    got = read_trials(eu)
    assert got.equals(plain) and got["comparison_um"].tolist() == [7.6, 12.4, 9.8]
    assert got.attrs["comments"] == ["synthetic, two subjects"]


def test_a_table_of_counts_appended_to_itself_is_refused(tmp_path):
    """Every row twice: read as twice the trials, with intervals to match. A second session
    sharing a few rows by chance, and a trial-by-trial file (rows repeat by nature), read."""
    head = ",".join(TRIAL_COLUMNS)
    rows = [f"S1,10,20,{x},20,20,{k}" for x, k in ((8, 2), (9, 6), (10, 10), (11, 15), (12, 19))]
    path = tmp_path / "twice.csv"
    path.write_text("\n".join(["# session 1", head] + rows + rows) + "\n")
    with pytest.raises(DataFileError) as info:
        read_trials(path)
    assert str(info.value) == (f"{path}: 5 of 10 rows repeat an earlier row in every field (e.g. line 8 = line 3): "
                               "the file was probably appended to itself, and the copies would count as more "
                               "trials; keep each row once")
    again = [f"S1,10,20,{x},20,20,{k}" for x, k in ((8, 2), (9, 7), (10, 11), (11, 14), (12, 19))]
    path.write_text("\n".join([head] + rows + again) + "\n")
    assert read_trials(path)["n_trials"].sum() == 200
    per_trial = tmp_path / "per_trial.csv"
    per_trial.write_text("\n".join([",".join(KEY_COLUMNS) + ",comparison_higher"] + ["S1,10,20,9,20,1"] * 6
                                   + ["S1,10,20,9,20,0"] * 4) + "\n")
    assert read_trials(per_trial)["n_comparison_higher"].tolist() == [6]


# --- psignifit's data matrix (height, n correct, n trials), read with the design it lacks ---------------------

MATRIX = np.array([[0.5, 9, 30], [1.0, 11, 30], [1.5, 17, 30], [2.0, 22, 30], [3.0, 28, 30]])


def _matrix_files(tmp_path) -> dict:
    """The one matrix as a lab that used psignifit may have it on disk."""
    files = {"savetxt": tmp_path / "savetxt.txt", "comma": tmp_path / "comma.csv",
             "header": tmp_path / "header.csv", "semicolon": tmp_path / "semicolon.csv"}
    np.savetxt(files["savetxt"], MATRIX)                                  # spaces, 1.000000000000000000e+00
    files["comma"].write_text("\n".join(f"{x:g},{k:g},{n:g}" for x, k, n in MATRIX) + "\n")
    files["header"].write_text("level,nCorrect,nTotal\n" + files["comma"].read_text())
    files["semicolon"].write_text("\n".join(f"{x:g};{k:g};{n:g}".replace(".", ",") for x, k, n in MATRIX) + "\n")
    return files


@pytest.mark.parametrize("nafc, count", [(True, "n_correct"), (False, "n_comparison_higher")])
def test_a_psignifit_matrix_reads_as_the_table_with_its_design(tmp_path, nafc, count):
    from feeler.psydata import MatrixDesign

    design = MatrixDesign(subject="P1", standard_um=0.0 if nafc else 1.5, speed_mm_s=20.0,
                          comparison_speed_mm_s=40.0, nafc=nafc)
    table = tmp_path / "table.csv"
    table.write_text(",".join(KEY_COLUMNS + ("n_trials", count)) + "\n" + "\n".join(
        f"P1,{design.standard_um:g},20,{x:g},40,{n:g},{k:g}" for x, k, n in MATRIX) + "\n")
    expected = read_trials(table)
    for name, path in _matrix_files(tmp_path).items():
        got = read_trials(path, design=design)
        assert got.equals(expected), name
        assert got.attrs["trial_rows"] == 0


def test_a_matrix_sums_repeated_heights_and_names_its_subject_after_the_file(tmp_path):
    from feeler.psydata import MatrixDesign

    path = tmp_path / "observer7.csv"
    path.write_text("# session 1 and 2\n1.0,4,10\n2.0,8,10\n1.0,6,10\n")
    df = read_trials(path, design=MatrixDesign(standard_um=1.5, speed_mm_s=20))
    assert df["subject"].tolist() == ["observer7", "observer7"] and df["comparison_um"].tolist() == [1.0, 2.0]
    assert df["n_trials"].tolist() == [20, 10] and df["n_comparison_higher"].tolist() == [10, 8]
    assert df.attrs["comments"] == ["session 1 and 2"]


def test_a_matrix_without_its_design_says_what_to_give(tmp_path):
    from feeler.psydata import MatrixDesign

    path = _matrix_files(tmp_path)["savetxt"]
    with pytest.raises(DataFileError) as err:
        read_trials(path)
    text = str(err.value)
    assert text.startswith(f"{path}: a psignifit data matrix") and "\n" not in text
    assert "--standard-um and --speed-mm-s" in text and "n_correct or n_comparison_higher" in text
    with pytest.raises(DataFileError, match=r"give --speed-mm-s \(and"):
        read_trials(path, design=MatrixDesign(standard_um=0.0, nafc=True))


def test_a_design_for_a_table_with_its_own_columns_is_refused(tmp_path):
    from feeler.errors import ArgumentError
    from feeler.psydata import MatrixDesign

    path = _csv(tmp_path, "A,10,20,7.6,20,10,3")
    with pytest.raises(ArgumentError, match=r"--standard-um=10.0: only for a psignifit data matrix .* drop the option"):
        read_trials(path, design=MatrixDesign(standard_um=10.0, speed_mm_s=20.0))


@pytest.mark.parametrize("text, match", [
    ("1.0,0.3,10\n", r"line 1, column 2 \(n higher\): '0.3' looks like a proportion; the matrix holds counts "
                     r"\(n correct = proportion × n trials, here 3\)"),
    ("1.0,2.5,10\n", r"line 1, column 2 \(n higher\): '2.5' must be a whole number"),
    ("1.0,10,4\n", r"line 1, column 2 \(n higher\): 10 > column 3 \(n trials\) 4 \(psignifit's order"),
    ("1.0,4,10\n-2,3,10\n", r"line 2, column 1 \(height\): '-2' is negative: column 1 is the comparison's height, "
                            r"not its difference from the standard \(height = 1.5 µm \+ difference\)"),
    ("1.0,4,10\n0,3,10\n", r"line 2, column 1 \(height\): 0.0 must be finite and > 0"),
    ("level,k,n\n", "no data rows"),
    ("1.0,0,0\n2.0,0,0\n", "no trials"),
    ("1.0,4,10\n2.0,5,10\n" * 3, "appended to itself"),
])
def test_bad_matrices_are_named_line_and_column(tmp_path, text, match):
    from feeler.psydata import MatrixDesign

    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(DataFileError, match=match):
        read_trials(path, design=MatrixDesign(standard_um=1.5, speed_mm_s=20.0))


@pytest.mark.parametrize("design, match", [
    (dict(standard_um=0.0, speed_mm_s=20.0), r"--standard-um=0.0: a finite number > 0 \(0 only in nAFC"),
    (dict(standard_um=-1.0, speed_mm_s=20.0, nafc=True), r"--standard-um=-1.0: a finite number >= 0"),
    (dict(standard_um=1.0, speed_mm_s=float("nan")), "--speed-mm-s=nan"),
    (dict(standard_um=1.0, speed_mm_s=20.0, comparison_speed_mm_s=0.0), "--comparison-speed-mm-s=0.0"),
    (dict(standard_um=1.0, speed_mm_s=20.0, subject=" "), "--subject"),
])
def test_a_design_out_of_range_names_its_option(design, match):
    from feeler.errors import ArgumentError
    from feeler.psydata import MatrixDesign

    with pytest.raises(ArgumentError, match=match):
        MatrixDesign(**design).check()


def test_a_three_column_table_cut_short_is_not_taken_for_a_matrix(tmp_path):
    path = _csv(tmp_path, "A,10,3", header="subject,standard_um,n_correct")
    with pytest.raises(DataFileError, match="missing column"):
        read_trials(path)


def test_a_windows_1252_trial_table_reads_with_its_comment(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes(("# Versuchsperson Jürgen, Stufen in µm\n" + HEADER + "\nJ,10,20,7.6,20,20,4\n").encode("cp1252"))
    df = read_trials(path)
    assert df.attrs["comments"] == ["Versuchsperson Jürgen, Stufen in µm"] and df["n_trials"].tolist() == [20]


def test_a_directory_of_matrices_reads_one_subject_per_file(tmp_path):
    """psignifit users keep a file per subject: each is a subject named after its file, in
    natural order (s2 before s10), under the one design given."""
    from feeler.errors import ArgumentError
    from feeler.psydata import MatrixDesign

    lab = tmp_path / "lab"
    lab.mkdir()
    np.savetxt(lab / "s10.txt", MATRIX)
    (lab / "s2.csv").write_text("# session 2\n" + "\n".join(f"{x:g},{k:g},{n:g}" for x, k, n in MATRIX[:3]) + "\n")
    (lab / "notes.md").write_text("not data\n")
    design = MatrixDesign(standard_um=0.0, speed_mm_s=20.0, nafc=True)
    df = read_trials(lab, design=design)
    assert df["subject"].drop_duplicates().tolist() == ["s2", "s10"] and len(df) == 3 + len(MATRIX)
    assert df.attrs["comments"] == ["session 2"]
    alone = read_trials(lab / "s10.txt", design=design)
    pd_equal = df[df.subject == "s10"].reset_index(drop=True)
    assert pd_equal.equals(alone)
    with pytest.raises(DataFileError, match=r"lab: a directory: .* with --standard-um and --speed-mm-s"):
        read_trials(lab)
    with pytest.raises(ArgumentError, match=r"--subject='A': one file's subject; in lab/ each file's subject"):
        read_trials(lab, design=MatrixDesign(subject="A", standard_um=0.0, speed_mm_s=20.0, nafc=True))
    _csv(lab, "A,10,20,7.6,20,10,3")                                        # a full table among them: t.csv
    with pytest.raises(DataFileError, match=r"t.csv: not a psignifit data matrix .* as the other files of lab/ are"):
        read_trials(lab, design=design)
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataFileError, match="holds no data matrices"):
        read_trials(tmp_path / "empty", design=design)
