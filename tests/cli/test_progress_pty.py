"""Progress bars draw on a pseudo-terminal that reports no size (0x0), as under `script` or CI,
and long commands draw a bar there instead of their lines."""
import sys

from tests.cli._run import ENV, in_a_pty

CODE = ("import time\nfrom feeler.calib.progress import progress\n"
        "for _ in progress(range(3), desc='work', enabled=True):\n    time.sleep(0.05)\nprint('done')\n")


def test_bar_on_a_zero_size_pty():
    text = in_a_pty([sys.executable, "-c", CODE])
    assert "work:" in text and "0/3" in text and "done" in text          # a bar was drawn


def test_sbc_draws_a_bar_not_lines_on_a_terminal():
    text = in_a_pty([sys.executable, "-m", "feeler", "validate", "sbc", "--model", "matrix", "--n", "10",
                      "--scheduler", "serial"])
    assert "SBC ok" in text and "SBC datasets:" in text and "\r" in text                # a bar redrawn in place
    assert "/10 done," not in text                                                      # not the lines


def test_a_pty_with_only_columns_set_still_draws():
    """COLUMNS set, LINES not, the pty 0x0 (CI): tqdm must still get rows to draw in."""
    env = {**{k: v for k, v in ENV.items() if k != "LINES"}, "COLUMNS": "100"}
    text = in_a_pty([sys.executable, "-c", CODE], env=env)
    assert "work:" in text and "0/3" in text and "done" in text


TICKING = ("import time\nfrom tqdm import tqdm\nseen = []\nredraw = tqdm.refresh\n"
           "def counted(self, *a, **k):\n    seen.append(time.monotonic())\n    return redraw(self, *a, **k)\n"
           "tqdm.refresh = counted\n"
           "from feeler.calib.progress import stages\n"
           "step, close = stages('work', tick_s=0.05)\nstep('one long stage')\nt0 = time.monotonic()\n"
           "while not any(t - t0 >= 1.2 for t in seen) and time.monotonic() - t0 < 60:\n    time.sleep(0.05)\n"
           "close()\nprint('redrawn' if any(t - t0 >= 1.2 for t in seen) else 'never redrawn')\n")


def test_a_live_stage_line_keeps_its_clock_running():
    """No step for over a second: the line is redrawn anyway, its elapsed time moving on
    (a stage such as WeasyPrint's layout is never a frozen line)."""
    text = in_a_pty([sys.executable, "-c", TICKING])
    assert "redrawn" in text and "never redrawn" not in text
    assert "work: one long stage [00:00]" in text and "work: one long stage [00:01]" in text
