"""Progress bars draw on a pseudo-terminal that reports no size (0x0), as under `script` or CI."""
import os
import pty
import subprocess
import sys

from tests.cli._run import ENV, ROOT

CODE = ("import time\nfrom feeler.calib.progress import progress\n"
        "for _ in progress(range(3), desc='work', enabled=True):\n    time.sleep(0.05)\nprint('done')\n")


def test_bar_on_a_zero_size_pty():
    master, slave = pty.openpty()                       # a fresh pty: 0 rows, 0 columns
    env = {k: v for k, v in ENV.items() if k not in ("COLUMNS", "LINES")}
    proc = subprocess.Popen([sys.executable, "-c", CODE], cwd=ROOT, env=env, stdout=slave, stderr=slave)
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
    assert proc.wait(timeout=60) == 0
    os.close(master)
    text = b"".join(chunks).decode("utf-8", "replace")
    assert "work:" in text and "0/3" in text and "done" in text          # a bar was drawn
