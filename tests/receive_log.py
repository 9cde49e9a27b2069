"""A logger's view of a fixed-rate sampler, for the tests of codegen.logs: the rows a non-realtime
logger writes when it receives a robot's samples (numpy only; the kind of log codegen.logs.clock
rebuilds).

The robot samples on ticks k = 0, 1, ... (period ``tick``). Sample k reaches the logger after a
delay d_k >= 0: gamma-distributed (shape 2) with std ``delay_std``, plus, with probability
``late``, an extra U(1, 4) ms; rows are written in arrival order (a late sample holds back the
ones after it: they arrive bunched), stamped with the arrival time rounded to ``rounding``. With
probability ``repeat`` the logger writes a row before the new sample arrived: the row repeats the
previous row's values and that tick's sample never reaches the log.
"""
import numpy as np


def receive_time(N, tick=1e-3, seed=0, delay_std=0.4e-3, repeat=0.05, late=0.002, rounding=1e-4,
                 delay="gamma"):
    """(stamps (N,), tick of the sample each row carries (N,) int, repeated (N,) bool) for N ticks.
    ``delay="uniform"``: delays uniform over a width sqrt(12) delay_std (a logger polling at its
    own rate: the stamps' phase against the tick spread over a whole tick, as on a real Panda)."""
    rng = np.random.default_rng(seed)
    k = np.arange(N)
    d = (rng.uniform(0.0, np.sqrt(12.0) * delay_std, N) if delay == "uniform"
         else rng.gamma(2.0, delay_std / np.sqrt(2.0), N))
    big = rng.random(N) < late
    d[big] += rng.uniform(1e-3, 4e-3, big.sum())
    stamps = np.maximum.accumulate(k * tick + d)
    stamps = np.round(stamps / rounding) * rounding
    repeated = rng.random(N) < repeat
    repeated[0] = False
    source = k.copy()
    for i in np.flatnonzero(repeated):
        source[i] = source[i - 1]
    return stamps, source, repeated


def motion(t, n, seed=0):
    """Smooth multi-sine positions (N, n) (rad) and velocities at times ``t`` (N,)."""
    rng = np.random.default_rng(seed + 1000)
    q, qd = np.zeros((len(t), n)), np.zeros((len(t), n))
    for j in range(n):
        for h in range(1, 6):
            a, f, ph = rng.uniform(0.05, 0.3) / h, 0.1 * h * rng.uniform(1, 3), rng.uniform(0, 2 * np.pi)
            q[:, j] += a * np.sin(2 * np.pi * f * t + ph)
            qd[:, j] += 2 * np.pi * f * a * np.cos(2 * np.pi * f * t + ph)
    return q, qd
