"""Input sequences for the bit-exact harness, by filter kind.

Each generator takes a numpy Generator and a length and returns the run()
arguments. They cover ordinary signals and the corners: steps, ramps,
sweeps, constant gyro bias, large and tiny magnitudes, zero vectors (the
accelerometer/magnetometer guards) and non-finite samples (the skip policy).
"""
import zlib

import numpy as np

N = 1000


def _sweep(n, f0=0.01, f1=20.0, rate=100.0):
    t = np.arange(n) / rate
    return np.sin(2 * np.pi * (f0 * t + (f1 - f0) * t * t / (2 * t[-1])))


def _seq1d():
    s = {}
    s["random"] = lambda g, n: (g.normal(0, 1, n), g.normal(0, 0.5, n))
    s["random_small"] = lambda g, n: (g.normal(0, 1e-3, n), g.normal(0, 1e-3, n))
    s["zero"] = lambda g, n: (np.zeros(n), np.zeros(n))
    s["step_angle"] = lambda g, n: (np.zeros(n), np.where(np.arange(n) >= n // 10, 0.5, 0.0))
    s["step_rate"] = lambda g, n: (np.where(np.arange(n) >= n // 10, 1.0, 0.0), np.zeros(n))
    s["ramp"] = lambda g, n: (np.full(n, 0.3), 0.3 * np.arange(n) / 100.0)
    s["ramp_noisy"] = lambda g, n: (0.3 + g.normal(0, 0.05, n),
                                    0.3 * np.arange(n) / 100.0 + g.normal(0, 0.02, n))
    s["sweep"] = lambda g, n: (np.gradient(_sweep(n)) * 100.0, _sweep(n))
    s["sweep_rate_only"] = lambda g, n: (_sweep(n) * 3.0, np.zeros(n))
    s["gyro_bias"] = lambda g, n: (np.full(n, 0.05) + g.normal(0, 0.01, n), g.normal(0, 0.02, n))
    s["gyro_bias_large"] = lambda g, n: (np.full(n, -2.0), np.zeros(n))
    s["sine_motion"] = lambda g, n: (0.8 * np.cos(np.arange(n) / 50) + 0.02,
                                     0.4 * np.sin(np.arange(n) / 50) + g.normal(0, 0.01, n))
    s["large"] = lambda g, n: (g.normal(0, 1e4, n), g.normal(0, 1e3, n))
    s["huge"] = lambda g, n: (g.normal(0, 1e30, n), g.normal(0, 1e30, n))
    s["tiny"] = lambda g, n: (g.normal(0, 1e-30, n), g.normal(0, 1e-38, n))
    s["subnormal"] = lambda g, n: (g.normal(0, 1e-40, n), g.normal(0, 1e-310, n))
    s["alternating"] = lambda g, n: ((-1.0) ** np.arange(n) * 5.0, (-1.0) ** np.arange(n) * 0.7)
    s["uniform_wide"] = lambda g, n: (g.uniform(-35, 35, n), g.uniform(-3.2, 3.2, n))

    def nonfinite(g, n):
        w, a = g.normal(0, 1, n), g.normal(0, 0.5, n)
        w[g.integers(0, n, 20)] = np.nan
        a[g.integers(0, n, 20)] = np.inf
        w[g.integers(0, n, 5)] = -np.inf
        return w, a
    s["nonfinite"] = nonfinite
    s["overflow"] = lambda g, n: (np.full(n, 3e38), np.full(n, -3e38))
    s["quantised"] = lambda g, n: (np.round(g.normal(0, 1, n) * 131) / 131,
                                   np.round(g.normal(0, 0.5, n) * 16384) / 16384)
    return s


def _unit_rows(g, n, scale=1.0):
    v = g.normal(size=(n, 3))
    return scale * v / np.linalg.norm(v, axis=1, keepdims=True)


def _seq3d(with_mag):
    s = {}

    def make(fn):
        def gen(g, n):
            gyr, acc, mag = fn(g, n)
            return (gyr, acc, mag) if with_mag else (gyr, acc)
        return gen

    def level(g, n):
        return (g.normal(0, 0.01, (n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)) + g.normal(0, 0.01, (n, 3)),
                np.tile([0.5, 0.0, -0.8], (n, 1)) + g.normal(0, 0.01, (n, 3)))
    s["level"] = make(level)
    s["random"] = make(lambda g, n: (g.normal(0, 1, (n, 3)), g.normal(0, 1, (n, 3)), g.normal(0, 1, (n, 3))))
    s["random_units"] = make(lambda g, n: (g.normal(0, 0.5, (n, 3)), _unit_rows(g, n, 9.81),
                                           _unit_rows(g, n, 48.0)))
    s["tilted_static"] = make(lambda g, n: (np.zeros((n, 3)), np.tile([0.3, -0.5, 0.8], (n, 1)),
                                            np.tile([0.2, 0.4, -0.6], (n, 1))))
    s["upside_down"] = make(lambda g, n: (g.normal(0, 0.01, (n, 3)), np.tile([0.0, 0.0, -1.0], (n, 1)),
                                          np.tile([0.5, 0.0, 0.8], (n, 1))))

    def rotating(g, n):
        t = np.arange(n) / 200.0
        gyr = np.column_stack([0.5 * np.sin(t), 0.3 * np.cos(2 * t), np.full(n, 0.2)])
        return gyr, _unit_rows(g, n) * 0.1 + [0, 0, 1], _unit_rows(g, n) * 0.1 + [0.4, 0, -0.9]
    s["rotating"] = make(rotating)
    s["fast_spin"] = make(lambda g, n: (np.tile([20.0, -15.0, 30.0], (n, 1)) + g.normal(0, 1, (n, 3)),
                                        g.normal(0, 1, (n, 3)), g.normal(0, 1, (n, 3))))
    s["gyro_bias"] = make(lambda g, n: (np.tile([0.02, -0.03, 0.01], (n, 1)) + g.normal(0, 0.005, (n, 3)),
                                        np.tile([0.0, 0.0, 1.0], (n, 1)) + g.normal(0, 0.01, (n, 3)),
                                        np.tile([0.5, 0.0, -0.8], (n, 1))))
    s["steps"] = make(lambda g, n: (np.where(np.arange(n)[:, None] % 200 < 100, 1.0, -1.0) * [0.5, 0.2, -0.3],
                                    np.where(np.arange(n)[:, None] % 300 < 150, [0.0, 0.0, 1.0], [0.5, 0.0, 0.86]),
                                    np.tile([0.5, 0.1, -0.8], (n, 1))))
    s["sweep"] = make(lambda g, n: (np.column_stack([_sweep(n), 0.5 * _sweep(n), -_sweep(n)]),
                                    np.column_stack([0.1 * _sweep(n), np.zeros(n), np.ones(n)]),
                                    np.tile([0.4, 0.0, -0.9], (n, 1))))
    s["large"] = make(lambda g, n: (g.normal(0, 1e3, (n, 3)), g.normal(0, 1e4, (n, 3)), g.normal(0, 1e4, (n, 3))))
    s["tiny"] = make(lambda g, n: (g.normal(0, 1e-20, (n, 3)), g.normal(0, 1e-15, (n, 3)), g.normal(0, 1e-15, (n, 3))))

    def zero_acc(g, n):
        gyr, acc, mag = g.normal(0, 0.3, (n, 3)), _unit_rows(g, n), _unit_rows(g, n)
        acc[g.random(n) < 0.2] = 0.0
        return gyr, acc, mag
    s["zero_acc"] = make(zero_acc)

    def zero_mag(g, n):
        gyr, acc, mag = g.normal(0, 0.3, (n, 3)), _unit_rows(g, n) + [0, 0, 2], _unit_rows(g, n)
        mag[g.random(n) < 0.3] = 0.0
        return gyr, acc, mag
    s["zero_mag"] = make(zero_mag)
    s["all_zero"] = make(lambda g, n: (np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))))
    s["zero_gyro"] = make(lambda g, n: (np.zeros((n, 3)), _unit_rows(g, n), _unit_rows(g, n)))

    def nonfinite(g, n):
        gyr, acc, mag = g.normal(0, 0.3, (n, 3)), _unit_rows(g, n) + [0, 0, 1], _unit_rows(g, n)
        for arr, bad in ((gyr, np.nan), (acc, np.inf), (mag, -np.inf), (acc, np.nan)):
            arr[g.integers(0, n, 10), g.integers(0, 3, 10)] = bad
        return gyr, acc, mag
    s["nonfinite"] = make(nonfinite)
    s["overflow"] = make(lambda g, n: (np.full((n, 3), 3e38), np.full((n, 3), -3e38), np.full((n, 3), 3e38)))
    s["quantised"] = make(lambda g, n: (np.round(g.normal(0, 1, (n, 3)) * 131) / 131,
                                        np.round((_unit_rows(g, n) * 0.2 + [0, 0, 1]) * 16384) / 16384,
                                        np.round(_unit_rows(g, n) * 1090) / 1090))
    s["nearly_vertical"] = make(lambda g, n: (g.normal(0, 0.2, (n, 3)),
                                              np.tile([1.0, 0.0, 1e-3], (n, 1)) + g.normal(0, 1e-3, (n, 3)),
                                              np.tile([0.0, 0.5, -0.8], (n, 1))))
    return s


SEQUENCES = {"1d": _seq1d(), "imu": _seq3d(False), "ahrs": _seq3d(True)}


def generate(kind, name, seed=0, n=N):
    g = np.random.default_rng([zlib.crc32(f"{kind}/{name}".encode()), seed])
    return SEQUENCES[kind][name](g, n)
