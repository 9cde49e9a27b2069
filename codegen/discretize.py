"""ObserverSpec -> fixed-step step Function (DESIGN §4: discretisation is a visible choice).

    step(x, y_prev, y, u_prev, u, p, active) -> (x_next, est)

``hold="zoh"``: y and u are held over [t_k, t_k+1]:
  1. x <- jump(x, y, p)              hybrid observers only (the logic state lives in x)
  2. est = output(x, y, u, p)        the estimate at this sample
  3. x_next = x advanced by dt with y and u held, in ``substeps`` equal sub-steps of
     ``method`` (explicit Euler or classical RK4). y_prev, u_prev and active are unused.

``hold="foh"`` (the default, codegen.target.DEFAULT_DISCRETIZATION): the state is first brought from t_k-1 to t_k with y interpolated linearly
between y_prev and y and u_prev held (the input that was applied over that interval), then
jump and output at t_k. Causal: it only uses samples already received. ``active`` = 0 on the
first sample after init (nothing to integrate yet). Why: an observer with output injection
through a gain k0 (e.g. x2hat = z + k0 y) sampled with y held settles at
a/(1 - exp(-a)) qd with a = k0 dt, a bias of ~a/2 that the linear hold removes.
"""
from __future__ import annotations

import casadi as ca

from .target import HOLDS, METHODS, Discretization  # noqa: F401  (re-exported)

# Above this many inlined RHS instructions (RHS size x stages x substeps) the stages call one
# shared RHS routine in the C instead: a big observer (I&I on a 6-DoF arm, an elastic 3R) stays
# small and quick to compile. Below it, inlining lets common subexpressions (sin/cos of a held y)
# be shared across stages.
INLINE_LIMIT = 15000


def integrator_step(f, x, t, h, method):
    """One explicit step of size h of x' = f(t, x) from time t."""
    if method == "euler":
        return x + h * f(t, x)
    k1 = f(t, x)
    k2 = f(t + h / 2, x + h / 2 * k1)
    k3 = f(t + h / 2, x + h / 2 * k2)
    k4 = f(t + h, x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def _symbols(spec, sym):
    return (sym("x", spec.nx), sym("y_prev", spec.ny), sym("y", spec.ny),
            sym("u_prev", spec.nu), sym("u", spec.nu), sym("p", spec.np), sym("active", 1))


def _advance(spec, x, y_of_t, u, p, dt, method, substeps):
    h = dt / substeps
    for i in range(substeps):
        x = integrator_step(lambda t, s: spec.rhs(s, y_of_t(t), u, p), x, i * h, h, method)
    return x


def _pieces(spec, dt, method, substeps, hold, inline):
    if inline == "auto":
        stages = {"euler": 1, "rk4": 4}[method] * substeps
        inline = spec.rhs.n_instructions() * stages <= INLINE_LIMIT
    x, yp, y, up, u, p, active = _symbols(spec, ca.SX.sym if inline else ca.MX.sym)
    if hold == "zoh":
        xj = spec.jump(x, y, p) if spec.jump is not None else x
        est = spec.output(xj, y, u, p)
        xn = _advance(spec, xj, lambda t: y, u, p, dt, method, substeps)
    else:
        # linear y over the last interval; active = 0 collapses it to no step at all
        xa = _advance(spec, x, lambda t: yp + (t / dt) * (y - yp), up, p, active * dt, method, substeps)
        xn = spec.jump(xa, y, p) if spec.jump is not None else xa
        est = spec.output(xn, y, u, p)
    return [x, yp, y, up, u, p, active], xn, est


def discretize(spec, disc, inline="auto"):
    """The step Function of a spec under a discretisation (see the module docstring).

    Parameters
    ----------
    spec : ObserverSpec
    disc : codegen.target.Discretization
        dt (s), method, hold, substeps.
    inline : "auto" or bool
        True: one flat SX expression; False: MX calling the spec's functions; "auto": by size.

    Returns
    -------
    casadi.Function
        ``step(x, y_prev, y, u_prev, u, p, active) -> (x_next, est)``.
    """
    ins, xn, est = _pieces(spec, disc.dt, disc.method, disc.substeps, disc.hold, inline)
    return ca.Function("step", ins, [xn, est],
                       ["x", "y_prev", "y", "u_prev", "u", "p", "active"], ["x_next", "est"])


def estimate(spec, disc, inline="auto"):
    """The estimate of ``discretize(spec, disc)`` as its own Function (same inputs), without
    advancing the state."""
    ins, _, est = _pieces(spec, disc.dt, disc.method, disc.substeps, disc.hold, inline)
    return ca.Function("estimate", ins, [est],
                       ["x", "y_prev", "y", "u_prev", "u", "p", "active"], ["est"])
