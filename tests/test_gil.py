"""run() loops in compiled code without the GIL: another Python thread keeps
running while a long run() is in progress."""
import threading

import numpy as np

import imufuse_c


def test_run_releases_the_gil():
    n = 2_000_000
    rate, angle = np.zeros(n), np.zeros(n)
    f = imufuse_c.Mahony1DBias(0.01, kp=2.0, ki=0.3)
    ticks = [0]
    stop = threading.Event()
    started = threading.Event()

    def spin():
        started.set()
        while not stop.is_set():
            ticks[0] += 1

    t = threading.Thread(target=spin)
    t.start()
    started.wait()
    try:
        before = ticks[0]
        f.run(rate, angle)          # ~25 ms of C; with the GIL held, spin() could not tick
        during = ticks[0] - before
    finally:
        stop.set()
        t.join()
    assert during > 1000, during
