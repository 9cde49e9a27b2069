"""Fixed-step integrators of the reference (DESIGN §4: zero-order hold on y, u).

``f`` is the flow x -> xdot with y, u, p already held constant over the step.
"""
from __future__ import annotations

METHODS = ("euler", "rk4")


def euler_step(f, x, h):
    """x + h f(x)."""
    return x + h * f(x)


def rk4_step(f, x, h):
    """Classical Runge-Kutta: x + h/6 (k1 + 2 k2 + 2 k3 + k4)."""
    k1 = f(x)
    k2 = f(x + 0.5 * h * k1)
    k3 = f(x + 0.5 * h * k2)
    k4 = f(x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


_STEPS = {"euler": euler_step, "rk4": rk4_step}


def integrate(f, x, dt, method="rk4", substeps=1):
    """Advance x over dt by ``substeps`` equal steps h = dt / substeps of ``method``."""
    step = _STEPS[method]
    h = dt / substeps
    for _ in range(substeps):
        x = step(f, x, h)
    return x
