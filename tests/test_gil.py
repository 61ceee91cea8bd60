"""run() loops in compiled code without the GIL: another Python thread keeps
running while a long run() is in progress."""
import threading

import numpy as np
import pytest

import imufuse_c


def ticks_during(work):
    """How often another Python thread gets to run while work() runs."""
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
        work()
        during = ticks[0] - before
    finally:
        stop.set()
        t.join()
    return during


def _single_axis():
    n = 2_000_000
    f = imufuse_c.Mahony1DBias(0.01, kp=2.0, ki=0.3)
    return lambda: f.run(np.zeros(n), np.zeros(n))          # ~25 ms of C


def _fusion():
    """FusionAHRS.run() and outputs_batch() (Fusion's own API: dt per update)."""
    n = 300_000
    gyr, acc, mag = np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.tile([1.0, 0, 0], (n, 1))
    f = imufuse_c.FusionAHRS()
    return lambda: f.outputs_batch(f.run(gyr, acc, mag, dt=0.01))


def _robust():
    n = 300_000
    gyr, acc, mag = np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.tile([1.0, 0, 0], (n, 1))
    f = imufuse_c.RobustAHRS(0.01)
    return lambda: f.run(gyr, acc, mag)


@pytest.mark.parametrize("make", [_single_axis, _fusion, _robust], ids=["Mahony1DBias", "FusionAHRS",
                                                                         "RobustAHRS"])
def test_run_releases_the_gil(make):
    during = ticks_during(make())
    # with the GIL held, the other thread could not tick at all
    assert during > 1000, during
