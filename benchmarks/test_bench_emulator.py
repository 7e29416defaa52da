"""Round-trip latency of a status query over the emulator's pty (issue 4 §7).

The driver's ``status()`` (write ``?``, read and parse the report) against the Grbl
emulator in a separate process, as a ratio to a raw pty round trip in the same run: a
child process that answers every byte with the same 40-byte report, read back with plain
``os.read`` on the slave descriptor (no pyserial, no parsing). The ratio is the cost of the emulator and the protocol layers on top of
the pty and the process switch; the absolute microseconds go to ``extra_info``.
"""
import contextlib
import multiprocessing
import os
import select
import tty

from _ratios import best_seconds, record_ratio
from feeler.hardware.emulators import GrblConfig, emulator_process
from feeler.hardware.stage import Stage

REPORT = b"<Idle|MPos:0.000,0.000,0.000|FS:0,0>\r\n"
QUERIES = 50


def _echo_report(conn) -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    conn.send(os.ttyname(slave))
    while True:
        select.select([master], [], [])
        if os.read(master, 4096):
            os.write(master, REPORT)


@contextlib.contextmanager
def raw_pty_fd():
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_echo_report, args=(there,), daemon=True)
    child.start()
    try:
        fd = os.open(here.recv(), os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        yield fd
        os.close(fd)
    finally:
        child.terminate()
        child.join()


def raw_query(fd: int) -> bytes:
    os.write(fd, b"?")
    got = b""
    while not got.endswith(b"\n"):
        select.select([fd], [], [], 1.0)
        got += os.read(fd, 4096)
    return got


def test_status_round_trip_vs_raw_pty(benchmark):
    with raw_pty_fd() as fd:
        def raw_queries():
            for _ in range(QUERIES):
                assert raw_query(fd) == REPORT

        baseline = best_seconds(raw_queries, repeat=5) / QUERIES
    with emulator_process(GrblConfig()) as emu, Stage.open(emu.path) as stage:
        def driver_queries():
            for _ in range(QUERIES):
                stage.status()

        benchmark.pedantic(driver_queries, rounds=5, iterations=1)
    latency_s = benchmark.stats["min"] / QUERIES
    benchmark.extra_info["status_round_trip_us"] = latency_s * 1e6
    benchmark.extra_info["raw_pty_round_trip_us"] = baseline * 1e6
    print(f"\nstatus query round trip: {latency_s * 1e6:.0f} us via driver + emulator, "
          f"{baseline * 1e6:.0f} us raw pty")
    record_ratio(benchmark, "status round trip / raw pty round trip", latency_s / baseline,
                 "<= 5 (informational)")
    assert latency_s > 0
