"""Fixed-step integrators of the reference (docs/architecture.md §4).

``f(t, x)`` is the flow with p fixed; t is the time since the start of the interval, so a
first-order hold can interpolate y inside the step (zero-order hold simply ignores t); with
``integrate(..., midpoint=True)`` f also receives the midpoint time of its sub-step, where a split
flow's model is evaluated.
``etdrk4`` integrates a flow f(t, x) = N(t, x) - a D x (a scalar rate a >= 0 on the states of
the 0/1 mask D) by exponential time differencing RK4 [Cox & Matthews 2002, eq. (26)]; RK4 on the
states outside the mask and for a flow without a rate.
``expmid`` evaluates a family's model part m at the sub-step's midpoint configuration, at its
start and at its midpoint state (predicted with the first), and integrates the rest of the
flow, f(t, x, m) with the midpoint m held, by ETD-RK4: for f = N0 + N1 t - a x (m and the
injection of a linear y) that is exact (the generated C computes that exact value from f at the
step's two ends where f + a x does not depend on x; both agree to rounding). ``expmid1`` is
expmid with the model's last value in place of m0 in the prediction (the step's memory).
"""
from __future__ import annotations

import math

import numpy as np

METHODS = ("euler", "rk4", "etdrk4", "expmid", "expmid1")
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
    """Classical Runge-Kutta: x + h/6 (k1 + 2 k2 + 2 k3 + k4); f, t, x, h as in ``euler_step``."""
    k1 = f(t, x)
    k2 = f(t + 0.5 * h, x + 0.5 * h * k1)
    k3 = f(t + 0.5 * h, x + 0.5 * h * k2)
    k4 = f(t + h, x + h * k3)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def phi(z):
    """(e^z, phi_1, phi_2, phi_3) at a real z, phi_k(z) = sum_{j>=0} z^j / (j+k)!: the series
    summed to convergence for |z| < 1, the expm1 closed forms otherwise."""
    if abs(z) < 1.0:
        out = []
        for k in (1, 2, 3):
            term, total, j = 1.0 / math.factorial(k), 0.0, 0
            while total + term != total:
                total += term
                j += 1
                term *= z / (j + k)
            out.append(total)
        return (math.exp(z), *out)
    e = math.expm1(z)
    return math.exp(z), e / z, (e - z) / z ** 2, (e - z - 0.5 * z * z) / z ** 3


def etdrk4_step(f, t, x, h, a, mask):
    """One ETD-RK4 step of length h (s) of x' = f(t, x) whose linear part is -a x on the states of
    ``mask``; f, t, x as in ``euler_step``, a (1/s) a scalar, mask (m,) 0/1."""
    D = np.asarray(mask, dtype=float)
    E, p1h = phi(-0.5 * a * h)[:2]
    E2, p1, p2, p3 = phi(-a * h)
    w1, w2, w3 = p1 - 3.0 * p2 + 4.0 * p3, p2 - 2.0 * p3, 4.0 * p3 - p2

    def N(s, xs):
        return f(s, xs) + a * D * xs
    c = 0.5 * h * p1h
    n1 = N(t, x)
    xa = np.where(D > 0, E * x + c * n1, x + 0.5 * h * n1)
    n2 = N(t + 0.5 * h, xa)
    xb = np.where(D > 0, E * x + c * n2, x + 0.5 * h * n2)
    n3 = N(t + 0.5 * h, xb)
    xc = np.where(D > 0, E * xa + c * (2.0 * n3 - n1), x + h * n3)
    n4 = N(t + h, xc)
    etd = E2 * x + h * (w1 * n1 + 2.0 * w2 * (n2 + n3) + w3 * n4)
    return np.where(D > 0, etd, x + (h / 6.0) * (n1 + 2.0 * n2 + 2.0 * n3 + n4))


def expmid_step(f, model, t, x, h, a, mask, m_last=None, correction=False):
    """One step of length h (s) of the method expmid from t (s) and x (m,): the model at the
    step's midpoint configuration and its start, m0 = model(t + h/2, t, x); the state at the
    step's midpoint predicted over h/2 with m0 held (exponential Euler with the flow at
    t + th h/2, th = phi_2(-a h/2) / phi_1(-a h/2), 1/2 without a rate: x_mid = e^(-a h/2) x +
    h/2 phi_1(-a h/2) (f + a x) on the mask, x + h/2 f elsewhere, exact for forcing linear in
    time); the model there, m = model(t + h/2, t + h/2, x_mid); then x' = f(s, x, m) with m
    held by ``etdrk4_step`` (``rk4_step`` when a is None). f: (s, x, m) -> x'; model:
    (t_cfg, t, x) -> the model at the configuration y(t_cfg) and the velocity x and y(t) give
    it; a, mask as in ``etdrk4_step``; ``m_last`` (the method expmid1): the model's last value,
    used by the prediction in place of m0 (the model then evaluated once); ``correction`` (a
    model part that corrects a flow complete without it, under expmid1): the prediction with
    f(s, x, None), the flow without it. Returns (x(t + h), m)."""
    m0 = None if correction else (model(t + 0.5 * h, t, x) if m_last is None else m_last)
    if a is None:
        x_mid = x + 0.5 * h * f(t + 0.25 * h, x, m0)
    else:
        E, p1, p2 = phi(-0.5 * a * h)[:3]
        n = f(t + 0.5 * h * p2 / p1, x, m0)
        x_mid = np.where(np.asarray(mask) > 0, E * x + 0.5 * h * p1 * (n + a * x), x + 0.5 * h * n)
    m = model(t + 0.5 * h, t + 0.5 * h, x_mid)

    def held(s, xs):
        return f(s, xs, m)
    return (etdrk4_step(held, t, x, h, a, mask) if a is not None else rk4_step(held, t, x, h)), m


def integrate_expmid(f, model, x, dt, substeps, rate=None, mask=None, memory=None, correction=False):
    """(x(dt), memory): ``substeps`` steps h = dt / substeps of ``expmid_step`` from x (m,); f,
    model, rate, mask, correction as there (t in [0, dt], s). ``memory`` (expmid1): the model's
    last value, each step's prediction then uses the one before it and the memory returned is the
    last step's model (None: expmid, or a correction under expmid1, returned as None)."""
    h = dt / substeps
    for i in range(substeps):
        x, m = expmid_step(f, model, i * h, x, h, rate, mask, memory, correction)
        memory = None if memory is None else m
    return x, memory


_STEPS = {"euler": euler_step, "rk4": rk4_step}


def integrate(f, x, dt, method="rk4", substeps=1, rate=None, mask=None, midpoint=False):
    """Advance x over dt by ``substeps`` equal steps h = dt / substeps of ``method``.

    Parameters
    ----------
    f : callable
        (t, x) -> x' (m,), t in [0, dt] the time since the start of the interval (s);
        with ``midpoint``, (t, x, t_mid) -> x', t_mid = (i + 1/2) h the midpoint of sub-step i
        (where a first-order hold freezes the model's configuration).
    x : (m,) array
    dt : float
        Sample time, s.
    method : {"euler", "rk4", "etdrk4"}
        ``etdrk4`` integrates -rate x exactly on the ``mask`` slots (plain RK4 when rate is None);
        for ``expmid`` see ``integrate_expmid``.
    substeps : int
    rate : float or None
        The family's gain rate a (1/s) of x' = g - a x.
    mask : sequence of int or None
        State slots the rate applies to.
    midpoint : bool
        Pass each sub-step's midpoint time to f (see f).

    Returns
    -------
    (m,) array
        x(dt).
    """
    h = dt / substeps
    for i in range(substeps):
        fi = (lambda t, xi, tm=(i + 0.5) * h: f(t, xi, tm)) if midpoint else f
        if method == "etdrk4" and rate is not None:
            x = etdrk4_step(fi, i * h, x, h, rate, mask)
        else:
            x = _STEPS["rk4" if method == "etdrk4" else method](fi, i * h, x, h)
    return x
