"""Progress bars draw on a pseudo-terminal that reports no size (0x0), as under `script` or CI,
and long commands draw a bar there instead of their lines."""
import os
import pty
import subprocess
import sys

from tests.cli._run import ENV, ROOT

CODE = ("import time\nfrom feeler.calib.progress import progress\n"
        "for _ in progress(range(3), desc='work', enabled=True):\n    time.sleep(0.05)\nprint('done')\n")


def _in_a_pty(argv: list[str], env: dict | None = None) -> str:
    """stdout and stderr of ``argv`` run on a fresh pseudo-terminal (0 rows, 0 columns)."""
    master, slave = pty.openpty()
    env = {k: v for k, v in ENV.items() if k not in ("COLUMNS", "LINES")} if env is None else env
    proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=slave, stderr=slave)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:                                 # EIO: the child closed the pty
            break
        if not data:
            break
        chunks.append(data)
    assert proc.wait(timeout=120) == 0
    os.close(master)
    return b"".join(chunks).decode("utf-8", "replace")


def test_bar_on_a_zero_size_pty():
    text = _in_a_pty([sys.executable, "-c", CODE])
    assert "work:" in text and "0/3" in text and "done" in text          # a bar was drawn


def test_sbc_draws_a_bar_not_lines_on_a_terminal():
    text = _in_a_pty([sys.executable, "-m", "feeler", "validate", "sbc", "--model", "matrix", "--n", "10",
                      "--scheduler", "serial"])
    assert "SBC ok" in text and "SBC datasets:" in text and "\r" in text                # a bar redrawn in place
    assert "/10 done," not in text                                                      # not the lines


def test_a_pty_with_only_columns_set_still_draws():
    """COLUMNS set, LINES not, the pty 0x0 (CI): tqdm must still get rows to draw in."""
    env = {**{k: v for k, v in ENV.items() if k != "LINES"}, "COLUMNS": "100"}
    text = _in_a_pty([sys.executable, "-c", CODE], env=env)
    assert "work:" in text and "0/3" in text and "done" in text
