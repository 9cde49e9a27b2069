"""Reduced-order observer with hybrid gain k_r (docs/papers/seed000.md §1.2–§1.3, seed 000), numpy.

    x2hat = z + k_r y,   z' = M(y)^{-1}[tau - C(y,x2hat) x2hat - F x2hat - g(y)] - k_r x2hat,  r' = 0
                                                                          [S000 (6),(9),(16)]
Jumps before each step [DERIVED, docs/papers/seed000.md §1.3]: while ||x2hat|| >= r vbar - eta and r < r_max,
r += 1; else while r >= 2 and ||x2hat|| <= (r-1) vbar - eta - delta, r -= 1; then
z+ = z + (k_r - k_{r+}) y, so x2hat is continuous.

The model at the estimate saturated to the declared velocity bound (HybridOptions.v_bound).
x = [z (n, rad/s); r], y = q (n, rad), u = tau (n, N m), p = [k_1 .. k_{r_max} (1/s), eta,
vbar, delta (rad/s)], est = x2hat (n, rad/s). r_max = len(p) - 3 (no fixed P_NAMES: the number
of gains is a build choice).
"""
from __future__ import annotations

import numpy as np

from . import reduced_order
from ._family import bound
from ._saturation import velocity_bound


def configure(robot, options):
    """This family with the declared velocity bound bound (HybridOptions.v_bound; ``robot`` the
    reference robot, ``options`` its HybridOptions)."""
    return bound(__name__, v_bound=velocity_bound(robot, options))


def _split(p):
    """(k_1..k_{r_max}, eta, vbar, delta)."""
    p = np.asarray(p, dtype=float)
    return p[:-3], p[-3], p[-2], p[-1]


def logic_state(r, r_max):
    """The logic state as an integer in [1, r_max] (nearest; clamped).

    Parameters
    ----------
    r : float
        The stored logic-state slot.
    r_max : int

    Returns
    -------
    int
    """
    return int(min(max(np.floor(r + 0.5), 1), r_max))


def gain(x, p):
    """k_r (1/s) for the logic state stored in x (n + 1,), p as in ``rhs``."""
    k = _split(p)[0]
    return k[logic_state(x[-1], len(k)) - 1]


def output(robot, x, y, u, p):
    """x2hat = z + k_r y  [S000 (9)].

    Parameters
    ----------
    robot : reference robot (n joints)
    x : (n + 1,) array
        [z (rad/s); r].
    y : (n,) array
        q, rad.
    u : (n,) array
        tau, N m (unused).
    p : (r_max + 3,) array
        [k_1 .. k_{r_max} (1/s); eta; vbar; delta (rad/s)].

    Returns
    -------
    (n,) array
        x2hat, rad/s.
    """
    return reduced_order.output(robot, x[:-1], y, u, [gain(x, p)])


def rhs_split(robot, x, y_cfg, y, u, p, v_bound=None):
    """[z'; r'] = [FD(y_cfg, sat(x2hat), tau) - k_r x2hat; 0]  [S000 (6)] (n + 1,), the model at the
    configuration y_cfg (n,) rad and at x2hat saturated to ``v_bound`` ((n,) rad/s or None);
    robot, x, y, u, p as in ``output``."""
    zdot = reduced_order.rhs_split(robot, x[:-1], y_cfg, y, u, [gain(x, p)], v_bound)
    return np.append(zdot, 0.0)


def rhs(robot, x, y, u, p, v_bound=None):
    """The flow [z'; r'] of the observer: ``rhs_split`` with the model at y itself;
    robot, x, y, u, p, v_bound as in ``rhs_split``."""
    return rhs_split(robot, x, y, y, u, p, v_bound)


def jump(robot, x, y, p):
    """[z+; r+] (n + 1,): the switching rule of docs/papers/seed000.md §1.3 (up- then down-jumps, repeated) with
    the z reset that keeps x2hat continuous [DERIVED]; robot, x, y, p as in ``output``."""
    k, eta, vbar, delta = _split(p)
    r_max = len(k)
    z = np.asarray(x[:-1], dtype=float)
    r0 = r = logic_state(x[-1], r_max)
    x2hat = z + k[r0 - 1] * y
    speed = np.sqrt(np.sum(x2hat * x2hat))
    while r < r_max and speed >= r * vbar - eta:
        r += 1
    while r >= 2 and speed <= (r - 1) * vbar - eta - delta:
        r -= 1
    z_plus = z + (k[r0 - 1] - k[r - 1]) * y     # [DERIVED] x2hat continuous at the jump
    return np.append(z_plus, float(r))


def phases(robot, x, y, p):
    """The states the parameter check linearises at: x itself, then each logic state r with
    x2hat along its direction ((1, .., 1) / sqrt(n) at rest) at the middle of r's band, speed
    max(0, (r - 1/2) vbar - eta - delta/2), where neither jump test fires; z = x2hat - k_r y.
    robot, x, y, p as in ``output``."""
    k, eta, vbar, delta = _split(p)
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    x2hat = x[:-1] + gain(x, p) * y
    norm = np.linalg.norm(x2hat)
    direction = x2hat / norm if norm > 0 else np.ones(len(y)) / np.sqrt(len(y))
    out = [x]
    for r in range(1, len(k) + 1):
        speed = max(0.0, (r - 0.5) * vbar - eta - 0.5 * delta)
        out.append(np.append(speed * direction - k[r - 1] * y, float(r)))
    return out


def rate(robot, x, p):
    """The gain rate k_r of the flow on z (r' = 0, so constant along it); robot, x, p as in
    ``output``."""
    return float(gain(x, p))


def rate_states(robot):
    """0/1 per state (n + 1,) of ``robot``: the linear gain term acts on z, not on r."""
    return np.append(np.ones(robot.n), 0.0)


def retune(robot, x, y, p_old, p_new):
    """z+ = z + (k_r(p_old) - k_r(p_new)) y, r unchanged: x2hat continuous at a change of gains;
    robot, x, y as in ``output``."""
    x = np.asarray(x, dtype=float)
    return np.append(x[:-1] + (gain(x, p_old) - gain(x, p_new)) * np.asarray(y, float), x[-1])


def init(robot, y0, est0, p):
    """x(0) = [x2hat(0) - k_1 y(0); 1] (n + 1,)  [S000 §V, CODE-KUKA]; y0 = q(0) (n,) rad,
    est0 = x2hat(0) (n,) rad/s, robot, p as in ``output``."""
    k = _split(p)[0]
    return np.append(np.asarray(est0, float) - k[0] * np.asarray(y0, float), 1.0)


def sizes(robot):
    """{"nx": n + 1, "ny": n, "nu": n, "nest": n}, n the joints of ``robot``."""
    n = robot.n
    return {"nx": n + 1, "ny": n, "nu": n, "nest": n}
