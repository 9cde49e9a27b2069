"""Fixed-step integrators of the reference (DESIGN §4).

``f(t, x)`` is the flow with p fixed; t is the time since the start of the interval, so a
first-order hold can interpolate y inside the step (zero-order hold simply ignores t).
"""
from __future__ import annotations

METHODS = ("euler", "rk4")
HOLDS = ("zoh", "foh")


def euler_step(f, t, x, h):
    """Explicit Euler: x + h f(t, x).

    Parameters
    ----------
    f : callable
        (t, x) -> x' (m,).
    t : float
        Time since the start of the sample interval, s.
    x : (m,) array
    h : float
        Step, s.

    Returns
    -------
    (m,) array
    """
    return x + h * f(t, x)


def rk4_step(f, t, x, h):
    """Classical Runge-Kutta: x + h/6 (k1 + 2 k2 + 2 k3 + k4); arguments as ``euler_step``."""
    k1 = f(t, x)
    k2 = f(t + 0.5 * h, x + 0.5 * h * k1)
    k3 = f(t + 0.5 * h, x + 0.5 * h * k2)
    k4 = f(t + h, x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


_STEPS = {"euler": euler_step, "rk4": rk4_step}


def integrate(f, x, dt, method="rk4", substeps=1):
    """Advance x over dt by ``substeps`` equal steps h = dt / substeps of ``method``.

    Parameters
    ----------
    f : callable
        (t, x) -> x' (m,), t in [0, dt] the time since the start of the interval (s).
    x : (m,) array
    dt : float
        Sample time, s.
    method : {"euler", "rk4"}
    substeps : int

    Returns
    -------
    (m,) array
        x(dt).
    """
    step = _STEPS[method]
    h = dt / substeps
    for i in range(substeps):
        x = step(f, i * h, x, h)
    return x
