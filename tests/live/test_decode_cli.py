"""`feeler decode`: offline it equals `classify` of the same scans; `--follow` keeps up with
a run being written (partial lines, a retried scan) and ends when the writer lets go."""

import threading
import time

import numpy as np
import pandas as pd
import pytest

from feeler.calib.neuron.live.follow import follow_rows, writer_active
from feeler.cli import main
from feeler.errors import DataFileError
from feeler.hardware.acquire.lock import lock_run_dir, release_run_dir


def _p_cols(frame):
    return [c for c in frame.columns if c.startswith("p_") and c.endswith("mm")]


def test_decode_equals_classify_of_the_same_run(fit_dir, scans_frame, tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    scans_frame.to_csv(run / "scans.csv", index=False)
    assert main(["decode", str(fit_dir), str(run), "--n-draws", "40", "--no-live"]) == 0
    out = capsys.readouterr()
    assert "decided" in out.out and "wrote" in out.out
    dec = pd.read_csv(run / "decisions.csv")
    assert main(["classify", str(fit_dir), str(run), "--n-draws", "40", "--out", str(tmp_path / "c")]) == 0
    cls = pd.read_csv(tmp_path / "c" / "classification.csv")
    np.testing.assert_array_equal(dec.scan_id, cls.scan_id)
    np.testing.assert_allclose(dec[_p_cols(dec)].to_numpy(), cls[_p_cols(cls)].to_numpy(), rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(dec[["height_mm", "lo90_mm", "hi90_mm"]].to_numpy(),
                               cls[["height_mm", "lo90_mm", "hi90_mm"]].to_numpy(), rtol=1e-9, atol=1e-12)
    assert {"decided_mm", "p_decided", "decided_at_t_s", "decided_at_x_mm", "flagged"} <= set(dec.columns)
    made = dec.dropna(subset=["decided_mm"])
    assert len(made) > 0 and (made.p_decided >= 0.9).all()
    assert main(["decode", str(fit_dir), str(run), "--n-draws", "40"]) == 2          # no silent overwrite
    err = capsys.readouterr().err                   # and the way on, as a follower of a resumed run needs it
    assert "decisions.csv: already exists; pass --force to replace it (the run is decoded again from its " \
           "first scan, as after `feeler acquire --resume`)" in err


def _writer(run, frame, release, chunks=7):
    """Write samples.csv in ragged chunks (cutting lines) while holding the run's lock; scan 0
    is first aborted half-way and retried as attempt 2."""
    fd = lock_run_dir(run)
    try:
        first = frame[frame.scan_id == frame.scan_id.iloc[0]]
        aborted = first.iloc[: len(first) // 2].assign(attempt=1)
        rows = pd.concat([aborted, frame.assign(attempt=np.where(frame.scan_id == first.scan_id.iloc[0], 2, 1))])
        text = rows.to_csv(index=False)
        cuts = np.linspace(0, len(text), chunks + 1).astype(int)
        with open(run / "samples.csv", "w") as f:
            for a, b in zip(cuts[:-1], cuts[1:]):
                f.write(text[a:b])
                f.flush()
                time.sleep(0.05)
        release.wait(10)
    finally:
        release_run_dir(fd)


def test_a_directory_of_one_file_per_scan_decodes_as_its_scans_csv(fit_dir, scans_frame, tmp_path, capsys):
    whole, lab = tmp_path / "whole", tmp_path / "lab"
    whole.mkdir(), lab.mkdir()
    scans_frame.to_csv(whole / "scans.csv", index=False)
    ids = sorted(scans_frame.scan_id.unique())
    for k, sid in enumerate(ids):
        scans_frame[scans_frame.scan_id == sid].to_csv(lab / f"touch{k}.csv", index=False)   # each with its own id
    for run in (whole, lab):
        assert main(["decode", str(fit_dir), str(run), "--n-draws", "40", "--no-live"]) == 0
    said = capsys.readouterr().out
    assert (f"{lab}: {len(ids)} scan files in name order (touch0.csv ... touch{len(ids) - 1}.csv) read as scan_id "
            f"{ids[0]} ... {ids[-1]}") in said
    a, b = (pd.read_csv(run / "decisions.csv") for run in (whole, lab))
    pd.testing.assert_frame_equal(a, b)


def test_follow_decodes_a_run_in_progress_like_offline(fit_dir, scans_frame, tmp_path, capsys):
    run = tmp_path / "live"
    run.mkdir()
    release = threading.Event()
    th = threading.Thread(target=_writer, args=(run, scans_frame, release))
    th.start()
    timer = threading.Timer(1.0, release.set)
    timer.start()
    try:
        assert main(["decode", str(fit_dir), str(run), "--follow", "--poll-s", "0.02", "--n-draws", "40",
                     "--no-live"]) == 0
    finally:
        release.set()
        th.join()
        timer.cancel()
    assert not writer_active(run)
    live = pd.read_csv(run / "decisions.csv")
    scans_frame.to_csv(tmp_path / "s.csv", index=False)
    assert main(["decode", str(fit_dir), str(tmp_path / "s.csv"), "--n-draws", "40", "--no-live"]) == 0
    off = pd.read_csv(tmp_path / "decisions.csv")
    pd.testing.assert_frame_equal(live.drop(columns="flag"), off.drop(columns="flag"), rtol=1e-12)


def test_follow_rows_keeps_a_partial_line_and_drops_a_cut_one(tmp_path):
    (tmp_path / "samples.csv").write_text("scan_id,t_s,uy_mm\n0,0.5,0.1\n0,1.0,0.")
    state = {"n": 0}

    def active():                               # the writer finishes the line, then one more cut line
        state["n"] += 1
        if state["n"] == 1:
            with open(tmp_path / "samples.csv", "a") as f:
                f.write("2\n1,0.5,0.3\n1,1")
            return True
        return False

    stats = {}
    rows = list(follow_rows(tmp_path, poll_s=0.001, active=active, sleep=lambda s: None, stats=stats))
    assert [r["uy_mm"] for r in rows] == ["0.1", "0.2", "0.3"] and stats["partial_lines_dropped"] == 1


def test_follow_on_a_finished_run_says_so_at_once(tmp_path):
    """--follow on a run that has its scans.csv and no writer waited --wait-s (30 s by
    default), then said only "no such file" (an outside audit): a finished run is named at
    once, with what to do; a run still to be written is waited for as before."""
    from feeler.errors import DataFileError

    (tmp_path / "scans.csv").write_text("scan_id,t_s,uy_mm\n0,0.5,0.1\n")
    naps = []
    with pytest.raises(DataFileError, match="holds a finished run .scans.csv.*decode it without --follow"):
        list(follow_rows(tmp_path, poll_s=1.0, wait_s=30.0, active=lambda: False, sleep=naps.append))
    assert naps == []
    (tmp_path / "scans.csv").unlink()
    with pytest.raises(DataFileError, match="no such file after 3 s"):
        list(follow_rows(tmp_path, poll_s=1.0, wait_s=3.0, active=lambda: False, sleep=naps.append))
    assert naps == [1.0, 1.0, 1.0]


def test_follow_rows_of_a_decimal_comma_logger(tmp_path):
    """A lab's own logger in a German locale: ';' between columns, ',' as decimal mark, a BOM."""
    (tmp_path / "samples.csv").write_text("\ufeffscan_id;t_s;uy_mm\n0;0,5;0,1\n0;1;0,25\n", encoding="utf-8")
    rows = list(follow_rows(tmp_path, poll_s=0.001, active=lambda: False, sleep=lambda s: None))
    assert rows == [{"scan_id": "0", "t_s": "0.5", "uy_mm": "0.1"}, {"scan_id": "0", "t_s": "1", "uy_mm": "0.25"}]


def test_follow_rows_skip_a_loggers_notes(tmp_path):
    """'#' lines a logger writes (its start, a new plate) are comments, as in every CSV
    feeler reads: the first was taken for the header."""
    (tmp_path / "samples.csv").write_text("# logger v2, sensor 12\nscan_id,t_s,uy_mm\n0,0.5,0.1\n# plate 2\n1,0.5,0.3\n")
    rows = list(follow_rows(tmp_path, poll_s=0.001, active=lambda: False, sleep=lambda s: None))
    assert rows == [{"scan_id": "0", "t_s": "0.5", "uy_mm": "0.1"}, {"scan_id": "1", "t_s": "0.5", "uy_mm": "0.3"}]


def test_follow_rows_stop_at_a_header_written_again(tmp_path):
    """A lab logger restarted onto the same file writes its header once more: the rows before
    it are decoded, then one line names where (not 'non-numeric value' in some column)."""
    (tmp_path / "samples.csv").write_text("scan_id,t_s,uy_mm\n0,0.5,0.1\n\n scan_id, t_s ,uy_mm\n0,0.5,0.2\n")
    got = []
    with pytest.raises(DataFileError) as info:
        for row in follow_rows(tmp_path, poll_s=0.001, active=lambda: False, sleep=lambda s: None):
            got.append(row)
    assert got == [{"scan_id": "0", "t_s": "0.5", "uy_mm": "0.1"}]
    assert str(info.value) == (f"{tmp_path / 'samples.csv'}: line 4 repeats the header (a logger restarted onto this "
                               "file?); delete the repeated header lines")


def test_follow_without_a_run_fails_in_one_line(fit_dir, tmp_path, capsys):
    with pytest.raises(DataFileError, match="no such file"):
        list(follow_rows(tmp_path, poll_s=0.01, wait_s=0.02, sleep=lambda s: None))
    assert main(["decode", str(fit_dir), str(tmp_path / "nowhere"), "--follow", "--wait-s", "0"]) == 2
    assert main(["decode", str(fit_dir), str(tmp_path / "nowhere")]) == 2
    assert main(["decode", str(fit_dir), str(tmp_path), "--follow", "--poll-s", "0"]) == 2
    err = capsys.readouterr().err
    said = [ln for ln in err.splitlines() if ln.startswith("feeler: ")]       # beside the first status lines
    assert len(said) == 3 and all(ln.startswith("feeler: error: ") for ln in said) and "Traceback" not in err


def test_decode_flags_a_batch_noisier_than_training_as_classify_does(fit_dir, scans_frame, tmp_path, capsys):
    """Scans named S1-T.. with 2 um more noise: decode says how the names became numbers, and
    judges the batch's read-out noise as classify does: every row is flagged with classify's
    reason. It only printed a note before, and `decode --follow` or `acquire --decode` not
    even that (an outside walk-through: 6 of 8 emulated scans decided at p 0.999, unflagged,
    where classify flagged all 8 as a quieter set-up). The batch is judged once 5 scans are
    in: the scans after that are not decided, and the decisions taken before it are said
    not to hold."""
    import numpy as np

    run = tmp_path / "run"
    run.mkdir()
    rng = np.random.default_rng(3)
    scans_frame.assign(scan_id=[f"S1-T{int(v):02d}" for v in scans_frame.scan_id],
                       uy_mm=scans_frame.uy_mm + 0.002 * rng.standard_normal(len(scans_frame))
                       ).to_csv(run / "scans.csv", index=False)
    assert main(["decode", str(fit_dir), str(run), "--n-draws", "40", "--no-live"]) == 0
    said = capsys.readouterr().out
    assert "scan ids are names (S1-T00 ... S1-T88), read as scan_id 0 ... 11 in order of appearance" in said
    assert "note: every scan is flagged: these 12 scans' read-out noise (median" in said
    dec = pd.read_csv(run / "decisions.csv")
    assert len(dec) == 12 and dec.flagged.all()
    assert dec.decided_mm[5:].isna().all()                  # judged at the 5th scan's end: none decided after
    early = int(dec.decided_mm.notna().sum())
    if early:
        assert f"note: {early} decided scan{'s were' if early > 1 else ' was'} flagged after the decision" in said
    assert main(["classify", str(fit_dir), str(run), "--n-draws", "40", "--out", str(tmp_path / "c")]) == 0
    cls = pd.read_csv(tmp_path / "c" / "classification.csv")
    assert cls.flagged.all() and dec.flag.tolist() == cls.flag.tolist()


def _follow_while_written(fit_dir, run, writer, frame) -> None:
    """`decode --follow` of ``run`` while a thread's ``writer(run, frame)`` acquires it; exit 0."""
    th = threading.Thread(target=writer, args=(run, frame))
    th.start()
    try:
        assert main(["decode", str(fit_dir), str(run), "--follow", "--poll-s", "0.02", "--wait-s", "10",
                     "--n-draws", "40", "--no-live"]) == 0
    finally:
        th.join()

def test_a_follower_flags_the_batch_as_soon_as_its_scans_tell(fit_dir, scans_frame, tmp_path, capsys):
    """`decode --follow` (and `acquire --decode`, the same RunDecoder) judges the batch's
    noise after every scan: from the 5th scan on every row so far is flagged, the next scans
    are flagged from their first sample and not decided, and at the end decisions.csv's
    flags are classify's for the same run."""
    noisy = scans_frame.assign(uy_mm=scans_frame.uy_mm + 0.002 * np.random.default_rng(3).standard_normal(
        len(scans_frame)))
    run = tmp_path / "run"
    _follow_while_written(fit_dir, run, _scan_by_scan_writer, noisy)
    assert "note: every scan is flagged: these 12 scans' read-out noise" in capsys.readouterr().out
    live = pd.read_csv(run / "decisions.csv")
    assert live.flagged.all() and live.decided_mm[5:].isna().all()
    noisy.to_csv(tmp_path / "noisy.csv", index=False)
    assert main(["classify", str(fit_dir), str(tmp_path / "noisy.csv"), "--n-draws", "40",
                 "--out", str(tmp_path / "c")]) == 0
    assert live.flag.tolist() == pd.read_csv(tmp_path / "c" / "classification.csv").flag.tolist()


def _scan_by_scan_writer(run, frame):
    """Make RUN and write its samples scan by scan under the writer lock, as `acquire` does."""
    import json

    time.sleep(0.2)
    run.mkdir()
    fd = lock_run_dir(run)
    try:
        first = True
        for sid, rows in frame.groupby("scan_id", sort=False):
            rows.assign(attempt=0).to_csv(run / "samples.csv", index=False, header=first, mode="w" if first else "a")
            first = False
            with open(run / "journal.jsonl", "a") as f:
                f.write(json.dumps({"event": "scan_done", "scan_id": int(sid)}) + "\n")
            time.sleep(0.05)
    finally:
        release_run_dir(fd)


def test_a_run_with_no_batch_reason_is_decided_as_before(small_fit, scans_frame):
    """The fit's own scans: no batch reason, and each row's flags are the scan's own."""
    from feeler.calib.neuron.live import LiveDecoder
    from feeler.calib.neuron.live.run import RunDecoder

    decoder = RunDecoder(LiveDecoder(small_fit[1], seed=0, n_draws=40))
    for row in scans_frame.to_dict("records"):
        decoder.sample(row)
    decoder.end_scan()
    assert decoder.batch is None and decoder.live.batch is None
    assert not decoder.table().flagged.any() and decoder.table().decided_mm.notna().any()


def test_decisions_that_contradict_the_labels_are_a_warning(fit_dir, fresh_frame, tmp_path, capsys):
    """decode checks its decisions as classify checks its answers: right labels, no
    warning; two plates' labels exchanged, the decisions (each taken at probability >= 0.9)
    are named over-confident and the end-of-scan intervals as not holding."""
    fresh_frame.to_csv(tmp_path / "right.csv", index=False)
    assert main(["decode", str(fit_dir), str(tmp_path / "right.csv"), "--n-draws", "40", "--no-live"]) == 0
    assert "warning" not in capsys.readouterr().out
    swapped = fresh_frame.assign(step_mm=fresh_frame.step_mm.replace({0.05: 0.1, 0.1: 0.05}))
    swapped.to_csv(tmp_path / "swapped.csv", index=False)
    assert main(["decode", str(fit_dir), str(tmp_path / "swapped.csv"), "--n-draws", "40", "--no-live",
                 "--force"]) == 0                          # decisions.csv lands beside the CSV: the first run's
    warnings = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("warning: ")]
    assert len(warnings) == 2, warnings
    assert "labels inside their 90 % interval" in warnings[0]
    assert "the decisions are over-confident for these scans" in warnings[1] and "right where their" in warnings[1]


def _stopped_writer(run, frame, delay_s=0.3):
    """Make RUN after ``delay_s`` (the follower is already waiting), then write its scans
    with their scan_done events, the last one stopped half-way (Ctrl-C or a crash)."""
    import json

    time.sleep(delay_s)
    run.mkdir()
    fd = lock_run_dir(run)
    try:
        ids = list(dict.fromkeys(frame.scan_id))
        last = frame[frame.scan_id == ids[-1]]
        rows = pd.concat([frame[frame.scan_id != ids[-1]], last.iloc[: len(last) // 2]]).assign(attempt=0)
        rows.to_csv(run / "samples.csv", index=False)
        with open(run / "journal.jsonl", "w") as f:
            for sid in ids[:-1]:
                f.write(json.dumps({"event": "scan_done", "scan_id": int(sid)}) + "\n")
            f.write(json.dumps({"event": "scan_start", "scan_id": int(ids[-1]), "attempt": 0}) + "\n")
        time.sleep(0.2)
    finally:
        release_run_dir(fd)


def test_follow_waits_for_the_run_and_leaves_out_a_scan_cut_short(fit_dir, scans_frame, tmp_path, capsys):
    """An audit: a follower started before `acquire` had made RUN exited 2 at once ("a run
    directory with --follow"), though --wait-s promises a wait; and when the acquisition
    stopped mid-scan, the follower wrote a row for the half scan (p = 0.999 for the wrong
    plate) that `decode` of the stopped run leaves out."""
    run = tmp_path / "later"
    _follow_while_written(fit_dir, run, _stopped_writer, scans_frame)
    said = capsys.readouterr()
    out = said.out
    ids = list(dict.fromkeys(scans_frame.scan_id))
    assert f"waiting up to 10 s for {run} to appear (--wait-s)" in said.err          # progress: stderr
    assert f"scan {ids[-1]} was cut short when the acquisition stopped: it gets no row in decisions.csv" in out
    live = pd.read_csv(run / "decisions.csv")
    assert list(live.scan_id) == ids[:-1]
    scans_frame[scans_frame.scan_id != ids[-1]].to_csv(tmp_path / "s.csv", index=False)
    assert main(["decode", str(fit_dir), str(tmp_path / "s.csv"), "--n-draws", "40", "--no-live"]) == 0
    off = pd.read_csv(tmp_path / "decisions.csv")
    pd.testing.assert_frame_equal(live.drop(columns="flag"), off.drop(columns="flag"), rtol=1e-12)
    assert main(["decode", str(fit_dir), str(tmp_path / "never"), "--follow", "--wait-s", "0.1"]) == 2
    err = capsys.readouterr().err
    line = err.strip().splitlines()[-1]
    assert line.startswith("feeler: error: argument RUN=") and line.endswith(
        "never': a run directory: none appeared in 0.1 s (--wait-s); start `feeler acquire --out RUN` too, or give "
        "a longer --wait-s"), line


def test_decode_says_when_the_runs_labels_are_not_plates_of_the_fit(fit_dir, scans_frame, tmp_path, capsys):
    """An audit decoded a four-plate run with a six-plate fit: the scans were flagged, but
    nothing said that the run's plates were not the fit's."""
    run = tmp_path / "run"
    run.mkdir()
    other = scans_frame.assign(step_mm=np.where(scans_frame.step_mm > 0, scans_frame.step_mm + 0.03, 0.0))
    other.to_csv(run / "scans.csv", index=False)
    assert main(["decode", str(fit_dir), str(run), "--n-draws", "40", "--no-progress"]) == 0
    said = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("note: ") and "no plate for" in ln]
    n = int((other.groupby("scan_id").step_mm.first() > 0).sum())
    assert len(said) == 1 and said[0].startswith(f"note: {n} of {other.scan_id.nunique()} scans are labelled with "
                                                 "steps the fit has no plate for ("), said
    assert "none of them can be decided as its label" in said[0]
    scans_frame.to_csv(run / "scans.csv", index=False)
    assert main(["decode", str(fit_dir), str(run), "--n-draws", "40", "--no-progress", "--force"]) == 0
    assert "no plate for" not in capsys.readouterr().out


def test_an_aborted_attempt_gets_no_line_of_its_own(small_fit, scans_frame):
    """A resumed run's samples.csv holds the stopped attempt of a scan, then the scan again
    from its start: the live lines showed an "end" line for the stopped half before the
    scan's own. Only the complete attempt is reported, once."""
    from feeler.calib.neuron.live import LiveDecoder
    from feeler.calib.neuron.live.run import RunDecoder

    ended = []
    decoder = RunDecoder(LiveDecoder(small_fit[1], seed=0, n_draws=40), on_scan=ended.append)
    ids = list(dict.fromkeys(scans_frame.scan_id))
    second = scans_frame[scans_frame.scan_id == ids[1]]
    rows = pd.concat([scans_frame[scans_frame.scan_id == ids[0]].assign(attempt=0),
                      second.iloc[: len(second) // 2].assign(attempt=0),              # stopped here
                      scans_frame[scans_frame.scan_id != ids[0]].assign(attempt=np.where(
                          scans_frame[scans_frame.scan_id != ids[0]].scan_id == ids[1], 1, 0))])
    for row in rows.to_dict("records"):
        decoder.sample(row)
    decoder.end_scan()
    assert [r["scan_id"] for r in ended] == ids
    assert ended[1]["n_samples"] == len(second)


def test_decode_counts_decided_scans_that_the_rest_of_the_scan_flags(fit_dir, scans_frame, tmp_path, capsys):
    """A scan is decided on what its samples so far show. A one-sample glitch of 50 um near
    each scan's end (its fifth-last sample) flags it only after its decision: decode's
    summary says how many decided scans were flagged later and that those decisions do not
    hold (decisions.csv has both columns; an outside audit found scans decided and flagged
    with nothing said)."""
    import numpy as np

    place = scans_frame.groupby("scan_id").cumcount(ascending=False).to_numpy() == 4
    glitched = scans_frame.assign(uy_mm=scans_frame.uy_mm + np.where(place, 0.05, 0.0))
    glitched.to_csv(tmp_path / "late.csv", index=False)
    assert main(["decode", str(fit_dir), str(tmp_path / "late.csv"), "--n-draws", "40", "--no-live"]) == 0
    said = capsys.readouterr().out
    table = pd.read_csv(tmp_path / "decisions.csv")
    both = int((table.decided_mm.notna() & table.flagged).sum())
    assert both > 0, said
    assert table.flag[table.flagged].str.contains(r"^U_y jumps \+\d+\.\d+ um at t = 18 s", regex=True).all()
    assert f"note: {both} decided scan{'s were' if both > 1 else ' was'} flagged later in the scan" in said
    assert "those decisions do not hold" in said


def test_decode_notes_copied_scans_as_classify_does(fit_dir, scans_frame, tmp_path, capsys):
    """classify notes scans that repeat another's U_y at every sample; decode said nothing."""
    ids = scans_frame.scan_id.unique()
    copy = scans_frame[scans_frame.scan_id == ids[0]].assign(scan_id=int(ids.max()) + 1)
    pd.concat([scans_frame, copy]).to_csv(tmp_path / "copies.csv", index=False)
    assert main(["decode", str(fit_dir), str(tmp_path / "copies.csv"), "--n-draws", "40", "--no-progress"]) == 0
    said = [ln for ln in capsys.readouterr().out.splitlines() if "repeat an earlier scan's U_y" in ln]
    assert said == [f"note: 1 of {len(ids) + 1} scans repeat an earlier scan's U_y at every sample (e.g. scan_id "
                    f"{int(ids.max()) + 1} = scan_id {ids[0]}): a scan copied under new ids, or a read-out that did "
                    f"not change between touches? Each copy is classified as that one scan, so they are not "
                    f"{len(ids) + 1} independent readings"]
