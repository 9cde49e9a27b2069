"""ObserverSpec -> step Function with the elapsed time as an input (docs/architecture.md §4: discretisation is
a visible choice).

    step(x, y_prev, y, u_prev, u, p, dt) -> (x_next, est)

dt (s) is the time the step integrates over, an input of the generated C like y and u: the C's
fixed-rate entry point (``<prefix>_step``) passes the designed Discretization.dt, its
``<prefix>_step_dt`` the elapsed time of a jittered loop or log, through this one kernel. The
ETD phi-functions are computed from z = -a dt / substeps at run time (``etd_coefficients``).

``hold="zoh"``: y and u are held over [t_k, t_k + dt]:
  1. x <- jump(x, y, p)              hybrid observers only (the logic state lives in x)
  2. est = output(x, y, u, p)        the estimate at this sample
  3. x_next = x advanced by dt with y and u held, in ``substeps`` equal sub-steps of
     ``method``. y_prev and u_prev are unused; dt is the time to the next sample.

``hold="foh"`` (the default, codegen.core.target.DEFAULT_DISCRETIZATION): the state is first brought
from t_k-1 to t_k = t_k-1 + dt with y interpolated linearly between y_prev and y and u_prev held
(the input that was applied over that interval), then jump and output at t_k. Causal: it only
uses samples already received. dt = 0 on the first sample after init (nothing to integrate
yet): the state is left as it is. The interpolation is written in the fraction s = (t - t_k-1)/dt
of the interval, y(s) = y_prev + s (y - y_prev) with y(0) = y_prev and y(1) = y exactly, so no
stage divides by dt.
A family that splits its flow's use of y (``spec.rhs_split(x, y_cfg, y, u, p)``: the model M, C,
g, F at the configuration y_cfg, the output-injection gain terms at y) has its model evaluated
once per sub-step, at the midpoint configuration y_cfg = y(t_i + h/2), while the gain terms see
y(t) linear: one configuration per sub-step instead of the three (t_i, t_i + h/2, t_i + h) of the
four RK4 stages, like the zero-order hold. The midpoint rule keeps the model's error at
O(h^3) per step, and with the gain terms exact (below) a ramp is still followed without bias.
Families without ``rhs_split`` see y(t) everywhere.

Methods: explicit Euler, classical RK4, ``"etdrk4"``: exponential time
differencing RK4 [Cox & Matthews, J. Comput. Phys. 176 (2002), eq. (26)] for a family that
declares a scalar gain rate a(x, p) on some states (``spec.rate``, ``spec.rate_states``), i.e.
a flow x' = N(t, x) - a D x, D the 0/1 diagonal of those states. With E = exp(-a h/2),
phi_1..3 the phi-functions of z = -a h (phi_1(z) = (e^z - 1)/z, ...):

    a_ = E x  + h/2 phi_1(z/2) N(x)           b_ = E x + h/2 phi_1(z/2) N(a_)
    c_ = E a_ + h/2 phi_1(z/2) (2 N(b_) - N(x))
    x+ = E^2 x + h [f1 N(x) + 2 f2 (N(a_) + N(b_)) + f3 N(c_)],
    f1 = phi_1 - 3 phi_2 + 4 phi_3,  f2 = phi_2 - 2 phi_3,  f3 = 4 phi_3 - phi_2

(the other states get classical RK4). It integrates the gain term exactly, keeps every
equilibrium of the flow (RK4 does, integrating-factor "Lawson" RK4 does not: at rest it leaves
z off -k0 y by the Simpson error of the forcing k0^2 y, 0.36 rad/s for ur5 at q = 1), and is
exact for forcing linear in t, so under the first-order hold a ramp y = v t gives est = v for
any k0 dt (the model at the midpoint configuration is constant over the sub-step). Why the
first-order hold: an observer with output injection through a gain k0 (x2hat = z + k0 y)
sampled with y held settles at a/(1 - R(-a)) qd with a = k0 dt and R the method's stability
function (RK4: R(-a) = 1 - a + a^2/2 - a^3/6 + a^4/24; exact: e^-a), a bias the linear hold
removes for every method.

``"expmid"``, the exponential midpoint rule, for a family that declares its model
part (``spec.model``, ``spec.rhs_model``: the flow is f(t, x) = F(t, x, m), m = model(x, y_cfg, y)
the forward dynamics, M, C, g and F, at the configuration y_cfg and the velocity x and y give
it; F is linear in x and in y(t): the gain and injection terms). With E = e^(-a h/2),
th = phi_2(-a h/2) / phi_1(-a h/2) (1/2 without a rate) and y_m = y(t + h/2):

    m0    = model(x, y_m, y(t))                                        the model at the start
    x_mid = E x + h/2 phi_1(-a h/2) [F(t + th h/2, x, m0) + a D x]     (Euler off the rate states)
    m     = model(x_mid, y_m, y_m)                                     the model at the midpoint
    x+    = x advanced by ETD-RK4 over h along x' = F(s, x, m), m held

(when F + a D x does not depend on x, as for the reduced-order families, F = N(s) - a D x with N
affine in s: x+ = e^(-a h) x + h phi_1 N(t) + h phi_2 (N(t + h) - N(t)), exact, the same as
ETD-RK4 to rounding with two evaluations of F instead of four; ``_affine_step``)

Both model evaluations are at the one configuration y_m: M(y_m), g(y_m) and the rest of the
configuration's work (sin/cos, transforms, articulated inertias) are computed once, the
velocity's (C, F) twice, against four times under "etdrk4" (inlined, by common subexpressions;
when the step calls the model, by ``model_parts``: a configuration call and two velocity
calls). The prediction is exact for forcing linear in time and the last line for the reduced-order families (F = m - k0 x2hat: linear forcing, rate
k0), so a ramp gives est = v for any k0 dt; the model's variation over the step enters at
O(h^3) per step. The step has no memory (the discrete map is x -> x+), so the stability check
linearises it as any other. Families without a model part get "etdrk4". Measured against
"etdrk4" (docs/architecture.md §4.1): on the built-in trajectory and MuJoCo's ur5 and panda it
moves the reduced-order and switched observers by at most 1.8 % of their own RMS error; the
extended-state observer, with the model held over the step, moved by 12 % on ur5 without
noise (3.5x on MuJoCo), so it declares no model part and keeps ETD-RK4.

``"expmid1"`` (the default, codegen.core.target.DEFAULT_DISCRETIZATION): ``"expmid"`` with the
model evaluated once per sub-step. The prediction of x_mid takes the model's last value m_-
(the previous sub-step's m) in place of m0; m, the model at the predicted midpoint, is held as
before and becomes the memory. The step's signature carries it:

    step(x, y_prev, y, u_prev, u, p, dt, m_prev) -> (x_next, est, m_next)

(m_prev and m_next with ``memory_size`` entries: the model's size under "expmid1", none under the
other methods). The C keeps it in its state struct beside y_prev; zeros after init and set_state
(the prediction then has no model for one sample; under the first-order hold the first sample
after init integrates nothing, dt = 0, and sets the memory to the model there). The stability
check linearises the map (x, m_prev) -> (x_next, m_next) (``step_jacobians``), so the memory's
effect is seen: on the model's own axis x' = -lambda x the method is stable for lambda h <= 1 (the
midpoint rule: 2), and a stiff damping or friction mode asks for more sub-steps. Measured against
"etdrk4" (docs/architecture.md §4.1): the reduced-order and switched observers move by at most
0.05 % of their own RMS error on the built-in trajectory and 2.8 % on MuJoCo's ur5 and panda; the
model held from the start state, without the memory, moved them by 10-11.5 %.

A model part that corrects a flow complete without it (``spec.model_correction``: kalman_model,
whose m is the a-measurement's gain structure at the midpoint configuration and velocity, and
m = 0 the kinematic filter) is predicted under "expmid1" with m = 0 in place of the memory:
x_mid from the flow without the correction, then m = model(x_mid, y_m, y_m) once, held while
ETD-RK4 evaluates rhs_model, and with it the correction's terms linear in the state, at each of
its four stages; no memory. Holding the correction itself over the step (the gains applied to
the midpoint state's innovation) moved kalman_model's RMS error on MuJoCo's ur5 by 6.7 % against
ETD-RK4 (its injection is far stiffer than its poles: a-gains omega^2 g_a4 ~ 5e3 / s^2).
"""
from __future__ import annotations

import math

import casadi as ca

from ..core.target import HOLDS, METHODS, Discretization  # noqa: F401  (re-exported)

# Above this many inlined RHS instructions (RHS size x stages x substeps) the stages call one
# shared RHS routine in the C instead: a big observer (I&I on a 6-DoF arm, an elastic 3R) stays
# small and quick to compile. Below it, inlining lets common subexpressions (sin/cos of a held y)
# be shared across stages. An inlined instruction is ~28 bytes of C, and under the first-order
# hold the estimate kernel holds the unrolled stages too: 10000 keeps both under ~300 KB each
# (the largest inlined default, panda reduced-order, has 7188; I&I AOV on ur5, 13320, was 0.74 MB
# of C for the two kernels at 15000).
INLINE_LIMIT = 10000

# the methods that hold a family's model part over a sub-step (ObserverSpec.model); "expmid1" keeps
# the model's last value as the step's memory
MODEL_METHODS = ("expmid", "expmid1")

_SERIES_TERMS = 17     # phi_k by its Taylor series for |z| < 1: remainder < 1/20! relative


def etd_coefficients(z):
    """(e^(z/2), phi_1(z/2), e^z, phi_1(z), phi_2(z), phi_3(z)) of one ETD-RK4 step, z = -a h
    (scalar SX/MX), phi_k(z) = sum_j z^j / (j + k)!, with a single exp:

        |z| < 1: phi_3 by its Taylor series (Horner), phi_2 = 1/2 + z phi_3, phi_1 = 1 + z phi_2
        else:    the closed forms of e^z - 1 (no cancellation there: e^z <= 1/e or >= e)
        phi_1(z/2) = 2 phi_1(z) / (1 + e^(z/2)),   e^z = (e^(z/2))^2

    No cancellation at z = 0 (a family whose rate is 0 gets exactly RK4's 1, 1/2, 1/6)."""
    small = ca.fabs(z) < 1
    zs = ca.if_else(small, 1, z)             # the closed forms never see z = 0
    E = ca.exp(z / 2)
    em1 = E * E - 1
    s = 1.0 / math.factorial(_SERIES_TERMS + 3)
    for j in range(_SERIES_TERMS - 1, -1, -1):
        s = s * z + 1.0 / math.factorial(j + 3)
    p3 = ca.if_else(small, s, (em1 - zs - zs ** 2 / 2) / zs ** 3)
    p2 = ca.if_else(small, 0.5 + z * p3, (em1 - zs) / zs ** 2)
    p1 = ca.if_else(small, 1 + z * p2, em1 / zs)
    return E, 2 * p1 / (1 + E), E * E, p1, p2, p3


def half_phi_functions(z):
    """(e^(z/2), phi_1(z/2), phi_2(z/2)) at a scalar SX/MX z, as ``etd_coefficients`` (series for
    |z/2| < 1, closed forms otherwise; e^(z/2) the same expression, shared)."""
    w = z / 2
    small = ca.fabs(w) < 1
    ws = ca.if_else(small, 1, w)
    E = ca.exp(z / 2)
    s = 1.0 / math.factorial(_SERIES_TERMS + 2)
    for j in range(_SERIES_TERMS - 1, -1, -1):
        s = s * w + 1.0 / math.factorial(j + 2)
    p2 = ca.if_else(small, s, (E - 1 - ws) / ws ** 2)
    p1 = ca.if_else(small, 1 + w * p2, (E - 1) / ws)
    return E, p1, p2


def phi_functions(z):
    """(e^z, phi_1(z), phi_2(z), phi_3(z)) (scalar SX/MX z), as ``etd_coefficients``."""
    return etd_coefficients(z)[2:]


def integrator_step(f, x, t, h, method, rate=None, mask=None, clock=None):
    """One step of size h of x' = f(t, x) from time t.

    ``method="etdrk4"`` with a scalar ``rate`` a and a 0/1 list ``mask`` (nx): the flow is
    N(t, x) - a D x with D = diag(mask), integrated by ETD-RK4 (module docstring); without a
    rate it is classical RK4. ``clock``: the step in the unit of f's time argument (default h):
    the stages see f at t, t + clock/2 and t + clock (e.g. the fraction of a sample interval
    whose length h is symbolic)."""
    c = h if clock is None else clock
    if method == "euler":
        return x + h * f(t, x)
    if method == "etdrk4" and rate is not None:
        return _etdrk4_step(f, x, t, h, rate, mask, c)
    k1 = f(t, x)
    k2 = f(t + c / 2, x + h / 2 * k1)
    k3 = f(t + c / 2, x + h / 2 * k2)
    k4 = f(t + c, x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def _etdrk4_step(f, x, t, h, a, mask, c):
    """ETD-RK4 of Cox & Matthews (2002) eq. (26) on the masked states, RK4 on the others; the
    stages see f at t, t + c/2, t + c."""
    D = ca.DM(mask)

    def pick(etd, rk4):
        return _masked(mask, etd, rk4)
    z = -a * h
    E, p1h, E2, p1, p2, p3 = etd_coefficients(z)
    f1, f2, f3 = p1 - 3 * p2 + 4 * p3, p2 - 2 * p3, 4 * p3 - p2

    def N(s, xs):
        return f(s, xs) + a * D * xs
    k1 = N(t, x)
    xa = pick(E * x + h / 2 * p1h * k1, x + h / 2 * k1)
    k2 = N(t + c / 2, xa)
    xb = pick(E * x + h / 2 * p1h * k2, x + h / 2 * k2)
    k3 = N(t + c / 2, xb)
    xc = pick(E * xa + h / 2 * p1h * (2 * k3 - k1), x + h * k3)
    k4 = N(t + c, xc)
    return pick(E2 * x + h * (f1 * k1 + 2 * f2 * (k2 + k3) + f3 * k4),
                x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))


def memory_size(spec, method):
    """Entries of the step's memory under the integrator ``method`` for ``spec``: the model's last
    value (``spec.model_size``) under "expmid1", 0 otherwise (a family without a model part gets
    ETD-RK4, which keeps none; one whose model part is a correction, ``spec.model_correction``,
    predicts without it)."""
    return spec.model_size if method == "expmid1" and not spec.model_correction else 0


def _symbols(spec, sym, nm=0):
    return (sym("x", spec.nx), sym("y_prev", spec.ny), sym("y", spec.ny),
            sym("u_prev", spec.nu), sym("u", spec.nu), sym("p", spec.np), sym("dt", 1), sym("m_prev", nm))


def rate_mask(spec):
    """0/1 per state: 1 where the family's linear gain term -a x acts (``spec.rate_states``)."""
    return [1 if name in spec.rate_states else 0 for name in spec.x_names]


def _masked(mask, etd, other):
    """etd on the states of the 0/1 ``mask``, ``other`` on the rest."""
    D = ca.DM(mask)
    return D * etd + (1 - D) * other if 0 < sum(mask) < len(mask) else (etd if sum(mask) else other)


def model_parts(model):
    """(configuration, velocity) with model(x, y_cfg, y, u, p) = velocity(x, y_cfg, y, u, p,
    configuration(y_cfg, p)): the configuration's work (sin/cos, transforms, articulated inertias,
    M, g) as its own Function, by ``casadi.extract_parametric`` (every largest subexpression of
    y_cfg and p alone becomes an input of the velocity part)."""
    x, yc, y, u, p = (ca.SX.sym(name, model.size1_in(i)) for i, name in enumerate(["x", "y_cfg", "y", "u", "p"]))
    velocity, symbols, parts = ca.extract_parametric(model(x, yc, y, u, p), ca.vertcat(yc, p))
    e = ca.vertcat(*symbols)
    return (ca.Function("model_cfg", [yc, p], [ca.vertcat(*parts)], ["y_cfg", "p"], ["cfg"]),
            ca.Function("model_vel", [x, yc, y, u, p, e], [velocity], ["x", "y_cfg", "y", "u", "p", "cfg"], ["m"]))


def _expmid_step(spec, x, y_of, u, p, t, h, c, rate, mask, parts=None, m_last=None, affine=False):
    """(x+, m) of one "expmid" sub-step (module docstring): the model at the midpoint
    configuration, at the sub-step's start and at its predicted midpoint state, the rest of the
    flow by ETD-RK4 with the midpoint model m held. ``parts``: the model's ``model_parts``, the
    configuration's part then evaluated once for both calls (MX steps, where the C calls the
    model instead of inlining it). ``m_last`` ("expmid1"): the model's last value, in place of
    the model at the start in the predictor (one model evaluation). ``affine``: the held flow's
    remainder is free of the state (``_remainder_is_stateless``), stepped by ``_affine_step``."""
    y0, y_mid = y_of(t), y_of(t + c / 2)
    if m_last is not None:
        parts = None
    if parts is None:
        def model(xs, ys):
            return spec.model(xs, y_mid, ys, u, p)
    else:
        e = parts[0](y_mid, p)

        def model(xs, ys):
            return parts[1](xs, y_mid, ys, u, p, e)
    m0 = model(x, y0) if m_last is None else m_last
    if rate is None:
        theta, E, p1 = 0.5, 1, 1
    else:
        E, p1, p2 = half_phi_functions(-rate * h)
        theta = p2 / p1
    # the flow at the fraction theta of the half step: exact for forcing linear in time
    n_theta = spec.rhs_model(x, y0 + theta * (y_mid - y0), u, p, m0)
    D = ca.DM(mask)
    x_mid = _masked(mask, E * x + h / 2 * p1 * (n_theta + (rate if rate is not None else 0) * D * x),
                    x + h / 2 * n_theta)
    m = model(x_mid, y_mid)
    if affine:
        return _affine_step(lambda s: spec.rhs_model(x, y_of(s), u, p, m) + (0 if rate is None else rate * D * x),
                            x, t, h, c, rate, mask), m
    return integrator_step(lambda s, xs: spec.rhs_model(xs, y_of(s), u, p, m), x, t, h, "etdrk4", rate,
                           mask, clock=c), m


def _remainder_is_stateless(spec):
    """True when the flow with the model given, N = rhs_model(x, y, u, p, m) + a D x, does not
    depend on x (its Jacobian in x is zero: the reduced-order families, N = m - k0^2 y): with m
    held and y linear in time, the flow over a sub-step is x' = N(t) - a D x, N affine in t."""
    f, rate = spec.rhs_model, spec.rate
    if not f.is_a("SXFunction") or (rate is not None and not rate.is_a("SXFunction")):
        return False
    x, y, u, p, m = f.sx_in()
    N = f(x, y, u, p, m) + (0 if rate is None else rate(x, p) * ca.DM(rate_mask(spec)) * x)
    J = ca.jacobian(N, x)
    return all(J.nz[i].is_zero() for i in range(J.nnz()))


def _affine_step(N, x, t, h, c, rate, mask):
    """x(t + h) of x' = N(s) - a D x exactly, N affine in time (given at the sub-step's ends, the
    clock c its length in N's time): on the states of ``mask`` e^(-a h) x + h phi_1 N0 +
    h phi_2 (N1 - N0) (phi_k at -a h), on the others x + h/2 (N0 + N1). Equal to ETD-RK4 of the
    same flow (which is exact for it too) to rounding, with two evaluations of N instead of four."""
    n0, n1 = N(t), N(t + c)
    rest = x + h / 2 * (n0 + n1)
    if rate is None:
        return rest
    E2, p1, p2 = etd_coefficients(-rate * h)[2:5]
    return _masked(mask, E2 * x + h * (p1 * n0 + p2 * (n1 - n0)), rest)


def _advance(spec, x, y_of, u, p, dt, method, substeps, midpoint=False, memory=None):
    """(x, memory) advanced over dt (s, symbolic), y = y_of(s) at the fraction s in [0, 1] of the
    interval; ``midpoint``: a family's model (``spec.rhs_split``) at the configuration
    y((i + 1/2)/substeps) of each sub-step i, its output injection at y(s). ``"expmid"``:
    ``_expmid_step`` per sub-step (ETD-RK4 for a family without a model part); ``"expmid1"``:
    the same with the model's last value ``memory`` in its predictor, the memory then the
    sub-step's model, or, for a model part that is a correction (``spec.model_correction``),
    with m = 0 in the predictor and no memory (other methods return ``memory`` as it came)."""
    if method in MODEL_METHODS and spec.model is None:
        method = "etdrk4"
    h = dt / substeps
    rate = spec.rate(x, p) if (spec.rate is not None and method in ("etdrk4",) + MODEL_METHODS) else None
    mask = rate_mask(spec)
    split = midpoint and spec.rhs_split is not None
    parts = model_parts(spec.model) if method == "expmid" and isinstance(x, ca.MX) else None
    affine = method in MODEL_METHODS and _remainder_is_stateless(spec)
    keep = method == "expmid1" and not spec.model_correction
    for i in range(substeps):
        if method in MODEL_METHODS:
            last = memory if keep else None
            if method == "expmid1" and spec.model_correction:
                last = ca.DM.zeros(spec.model_size)          # the flow without its correction predicts
            x, m = _expmid_step(spec, x, y_of, u, p, i / substeps, h, 1 / substeps, rate, mask, parts, last, affine)
            memory = m if keep else memory
            continue
        y_cfg = y_of((i + 0.5) / substeps)
        flow = ((lambda s, xs: spec.rhs_split(xs, y_cfg, y_of(s), u, p)) if split else
                (lambda s, xs: spec.rhs(xs, y_of(s), u, p)))
        x = integrator_step(flow, x, i / substeps, h, method, rate, mask, clock=1 / substeps)
    return x, memory


def _linear(y_prev, y):
    """y(s) = y_prev + s (y - y_prev) at a constant fraction s, exact at both ends."""
    def y_of(s):
        return y_prev if s == 0 else (y if s == 1 else y_prev + s * (y - y_prev))
    return y_of


def _inline(spec, method, substeps, inline):
    if inline != "auto":
        return bool(inline)
    model = spec.model is not None
    stages = {"euler": 1, "rk4": 4, "etdrk4": 4, "expmid": 2 if model else 4, "expmid1": 1 if model else 4}[method]
    return spec.rhs.n_instructions() * stages * substeps <= INLINE_LIMIT


def _pieces(spec, method, substeps, hold, inline, syms=None):
    inline = _inline(spec, method, substeps, inline)
    x, yp, y, up, u, p, dt, mp = syms or _symbols(spec, ca.SX.sym if inline else ca.MX.sym,
                                                   memory_size(spec, method))
    memory = mp if memory_size(spec, method) else None
    if hold == "zoh":
        xj = spec.jump(x, y, p) if spec.jump is not None else x
        est = spec.output(xj, y, u, p)
        xn, mn = _advance(spec, xj, lambda s: y, u, p, dt, method, substeps, memory=memory)
        flow = (xj, xn)
    else:
        # linear y over the last interval; dt = 0 collapses it to no step at all (the memory
        # then takes the model at the sample)
        xa, mn = _advance(spec, x, _linear(yp, y), up, p, dt, method, substeps, midpoint=True, memory=memory)
        xn = spec.jump(xa, y, p) if spec.jump is not None else xa
        est = spec.output(xn, y, u, p)
        flow = (x, xa)
    return [x, yp, y, up, u, p, dt, mp], xn, est, flow, (mp if mn is None else mn)


_NAMES_IN = ["x", "y_prev", "y", "u_prev", "u", "p", "dt", "m_prev"]


def _shared(outs):
    """SX outputs with every repeated subexpression computed once (``casadi.cse``): the stages of
    a step that see one configuration (zero-order hold, or a split flow's midpoint) share its
    model, trigonometry included, in the emitted C itself rather than by the C compiler's grace
    (gcc -O3 on x86-64 merges them too; the kernel files are ~20 % smaller)."""
    return ca.cse(outs) if isinstance(outs[0], ca.SX) else outs


def discretize(spec, disc, inline="auto"):
    """The step Function of a spec under a discretisation (see the module docstring).

    Parameters
    ----------
    spec : ObserverSpec
    disc : codegen.core.target.Discretization
        method, hold, substeps (its dt is what the C's fixed-rate entry point passes as dt).
    inline : "auto" or bool
        True: one flat SX expression; False: MX calling the spec's functions; "auto": by size.

    Returns
    -------
    casadi.Function
        ``step(x, y_prev, y, u_prev, u, p, dt, m_prev) -> (x_next, est, m_next)``, dt (s) the time
        integrated over (foh: since the last sample, 0 on the first; zoh: to the next sample),
        m_prev and m_next the step's memory (``memory_size``: the model's last value under
        "expmid1", 0 entries otherwise; zeros after init, when the first sample's predictor
        has no model).
    """
    ins, xn, est, _, mn = _pieces(spec, disc.method, disc.substeps, disc.hold, inline)
    return ca.Function("step", ins, _shared([xn, est, mn]), _NAMES_IN, ["x_next", "est", "m_next"])


def estimate(spec, disc, inline="auto"):
    """The estimate of ``discretize(spec, disc)`` as its own Function (same inputs, dt included),
    without advancing the state; ``spec`` the observer, ``disc`` its Discretization, ``inline``:
    True (SX), False (MX calls) or "auto" (SX when the unrolled step is small)."""
    ins, _, est, _, _ = _pieces(spec, disc.method, disc.substeps, disc.hold, inline)
    return ca.Function("estimate", ins, _shared([est]), _NAMES_IN, ["est"])


def step_jacobians(spec, disc, inline="auto"):
    """Linearisations of the step and of the flow, with the sample time as an input.

    Parameters
    ----------
    spec : ObserverSpec
        The observer.
    disc : Discretization
        Method, hold and substeps of the step (its dt is replaced by the input dt).
    inline : bool or "auto"
        SX (inlined) or MX expressions; "auto": SX when the unrolled step is small.

    Returns
    -------
    casadi.Function
        ``(x, y, u, p, dt) -> (dx_next/dx, J(x_a), J(x_b))``: the step of ``disc`` (its
        method, hold, substeps; its dt replaced by the input dt) at y_prev = y, u_prev = u
        (the measurement held over the sample, so a split flow's midpoint
        configuration is y too: the step the observer takes there), and the continuous-time Jacobian
        J = drhs/dx of the flow at both ends x_a, x_b of the step's flow (a hybrid jump, before
        or after it, is not part of the flow). A step with memory (``memory_size``: "expmid1")
        is linearised as the map (x, m) -> (x_next, m_next) of both, at the memory the held
        measurement gives, m = model(x, y, y, u, p): Phi is then (nx + nm) x (nx + nm).
    """
    inline = _inline(spec, disc.method, disc.substeps, inline)
    sym = ca.SX.sym if inline else ca.MX.sym
    nm = memory_size(spec, disc.method)
    # the state and the memory as one symbol v = (x, m): one Jacobian in it
    v, y, u, p, dt = (sym("v", spec.nx + nm), sym("y", spec.ny), sym("u", spec.nu), sym("p", spec.np), sym("dt"))
    x, m = v[:spec.nx], v[spec.nx:]
    _, xn, _, (xa, xb), mn = _pieces(spec, disc.method, disc.substeps, disc.hold, inline,
                                     syms=(x, y, y, u, u, p, dt, m))
    step = ca.Function("held_step", [v, y, u, p, dt], [ca.vertcat(xn, mn) if nm else xn, xa, xb])
    if not inline:
        # a step that calls its model: expanded first, its Jacobian then built in SX (at n = 24
        # 1.4 s against 2.1 s for the MX Jacobian expanded after)
        try:
            step = step.expand()
        except RuntimeError:
            pass
    v, y, u, p, dt = step.sx_in() if step.is_a("SXFunction") else step.mx_in()
    out, xa, xb = step(v, y, u, p, dt)
    xs = type(v).sym("x", spec.nx)
    J = ca.Function("J", [xs, y, u, p], [ca.jacobian(spec.rhs(xs, y, u, p), xs)])
    inner = ca.Function("jacobians", [v, y, u, p, dt], [ca.jacobian(out, v), J(xa, y, u, p), J(xb, y, u, p)])
    # with memory: at the model's value at the held measurement
    at = ca.vertcat(xs, spec.model(xs, y, y, u, p)) if nm else xs
    return ca.Function("step_jacobians", [xs, y, u, p, dt], inner(at, y, u, p, dt),
                       ["x", "y", "u", "p", "dt"], ["Phi", "J0", "J1"])
