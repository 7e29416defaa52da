"""No loop reads outside its arrays: strain and times are placed at the very end of a
readable page, followed by an unreadable one, so a read past the last sample is a
segmentation fault (caught by running the calls in a child process)."""
import subprocess
import sys
import textwrap

CHILD = textwrap.dedent("""
    import ctypes, mmap
    import numpy as np
    from feeler.models.neuron import FA1Stream, peak_window_sum, pulse_density, window_sum

    libc = ctypes.CDLL(None, use_errno=True)
    libc.mprotect.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    KEEP = []

    def fenced(values):
        # a copy of values that ends exactly where an unreadable page begins
        values = np.ascontiguousarray(values, dtype=np.float64)
        page = mmap.PAGESIZE
        data = -(-values.nbytes // page) * page
        buf = mmap.mmap(-1, data + page)
        base = ctypes.addressof(ctypes.c_char.from_buffer(buf))
        assert libc.mprotect(base + data, page, 0) == 0, ctypes.get_errno()  # PROT_NONE
        out = np.frombuffer(buf, dtype=np.float64, count=values.size, offset=data - values.nbytes)
        out[:] = values.ravel()
        KEEP.append(buf)
        return out.reshape(values.shape)

    rng = np.random.default_rng(0)
    for n in (700, 1 << 17):
        t = np.arange(n) * 1e-3
        t_jit = t + rng.uniform(0, 2e-4, n)
        eps = rng.normal(size=n).cumsum()
        for tau in (5e-4, 3e-3, 7.5e-3, 8e-3, 0.3, 2.0 * n * 1e-3):
            for tt in (t, t_jit):
                for kernel in ("boxcar", "exponential"):
                    want = window_sum(eps, tt, tau=tau, kernel=kernel)
                    got = window_sum(fenced(eps), fenced(tt), tau=tau, kernel=kernel)
                    assert np.array_equal(got, want), (n, tau, kernel)
                    peak = peak_window_sum(fenced(eps), fenced(tt), tau=tau, kernel=kernel)
                    assert np.array_equal(peak, peak_window_sum(eps, tt, tau=tau, kernel=kernel))
            rec = np.stack([eps, -eps, 0.5 * eps])   # three receptors, weighted
            w = np.array([0.2, 0.3, 0.5])
            assert np.array_equal(window_sum(fenced(rec), fenced(t), tau=tau, weights=w),
                                  window_sum(rec, t, tau=tau, weights=w))
            z = pulse_density(fenced(eps), fenced(t), a=2.0, tau=tau, h=0.1)
            assert np.array_equal(z, pulse_density(eps, t, a=2.0, tau=tau, h=0.1))
            stream = FA1Stream(a=1.0, tau=tau, h=0.0)
            parts = [stream.push(fenced(t[i:i + 300]), fenced(eps[i:i + 300])) for i in range(0, n, 300)]
            np.testing.assert_allclose(np.concatenate(parts), window_sum(eps, t, tau=tau),
                                       rtol=1e-9, atol=1e-12)
    print("ok")
""")


def test_no_loop_reads_past_the_last_sample():
    run = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and run.stdout.strip() == "ok", \
        f"child exit {run.returncode} (-11: a read outside the arrays): {run.stderr[-2000:]}"
