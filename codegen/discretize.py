"""ObserverSpec -> fixed-step step Function (DESIGN §4: discretisation is a visible choice).

    step(x, y, u, p) -> (x_next, est)

  1. x <- jump(x, y, p)            hybrid observers only (the logic state lives in x)
  2. est = output(x, y, u, p)      the estimate at this sample
  3. x_next = x advanced by dt with y and u held (zero-order hold), in ``substeps``
     equal sub-steps of ``method`` (explicit Euler or classical RK4).
"""
from __future__ import annotations

import casadi as ca

METHODS = ("euler", "rk4")


def integrator_step(f, x, h, method):
    """One explicit step of size h of x' = f(x)."""
    if method == "euler":
        return x + h * f(x)
    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def discretize(spec, dt, method="rk4", substeps=1):
    """The step Function of ``spec`` for step dt (s); see the module docstring."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if not (dt > 0) or not isinstance(substeps, int) or substeps < 1:
        raise ValueError(f"need dt > 0 and an integer substeps >= 1, got dt={dt!r}, substeps={substeps!r}")
    x, y = ca.SX.sym("x", spec.nx), ca.SX.sym("y", spec.ny)
    u, p = ca.SX.sym("u", spec.nu), ca.SX.sym("p", spec.np)
    xj = spec.jump(x, y, p) if spec.jump is not None else x
    est = spec.output(xj, y, u, p)
    h = dt / substeps
    xn = xj
    for _ in range(substeps):
        xn = integrator_step(lambda s: spec.rhs(s, y, u, p), xn, h, method)
    return ca.Function("step", [x, y, u, p], [xn, est], ["x", "y", "u", "p"], ["x_next", "est"])


def estimate(spec):
    """est = output(jump(x, y, p), y, u, p): the estimate of ``step`` without advancing the state."""
    x, y = ca.SX.sym("x", spec.nx), ca.SX.sym("y", spec.ny)
    u, p = ca.SX.sym("u", spec.nu), ca.SX.sym("p", spec.np)
    xj = spec.jump(x, y, p) if spec.jump is not None else x
    return ca.Function("estimate", [x, y, u, p], [spec.output(xj, y, u, p)], ["x", "y", "u", "p"], ["est"])
