"""Model-free non-smooth velocity observer of Su, Müller & Zheng as printed in seed 002
(docs/papers/seed002.md §3.3), literal form and the Xian-form variant.

Literal (35), states (qhat, w = qhat'):                                        [S002 (35)]
    qhat' = w
    w'    = -K0 sg(qhat - q) - (K1 + I) w - K2 (qhat - q),           qd_hat = w
Xian form, states (qhat, w = p):                                    [DERIVED] docs/papers/seed002.md §3.3, A2-5
    qhat' = w + (K1 + I)(q - qhat)
    w'    = K0 sg(q - qhat) + K2 (q - qhat),                         qd_hat = qhat'
    w(0)  = qhat'(0) - (K1 + I)(q(0) - qhat(0))

With e = qhat - q and the runtime switch ``xian`` in {0, 1} both are one set of equations
(exact for 0 and 1: the other form's terms are multiplied by an exact zero):
    qhat' = w - xian (K1 + 1) e
    w'    = -K0 sg(e) - K2 e - (1 - xian)(K1 + 1) w
    qd_hat = w - xian (K1 + 1) e
sg = sign when sgn_eps = 0, else tanh(e / sgn_eps) (smoothing for reproducible fixed steps,
docs/papers/seed002.md §3.3 suggests eps = 1e-4; default 0 = literal sign, run with dt <= 1e-4 s).

Vectors: x = [qhat (n), w (n)], y = q (n), u = tau (n) (unused: the observer is model-free;
kept so it takes the same inputs as every observer), est = [qd_hat (n), qhat (n)],
p = [K0 (n), K1 (n), K2 (n), xian, sgn_eps]. init from est0 = [qd_hat(0), qhat(0)]
(seed: qd_hat(0) = [2, 2], qhat(0) = [-1, -1]).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...core.options import InputRanges
from ...core.spec import ObserverSpec

# where the cross-checks build this family (targets-file entries; tests/families/test_coverage.py)
EXAMPLES = [{"robot": "seed002_2r"}, {"robot": "seed002_2r", "design": {"form": "xian", "smoothing_eps": 1e-4}}]

FORMS = ("literal", "xian")
SEED_GAINS = {"K0": 500.0, "K1": 10.0, "K2": 2000.0}   # [S002 §V-B]


def sg(e, eps):
    """sign(e) if eps == 0 else tanh(e / eps)  (eps a runtime parameter)."""
    return ca.if_else(eps > 0, ca.tanh(e / ca.fmax(eps, 1e-300)), ca.sign(e))


def build(robot, form="literal", smoothing_eps=None, K0=None, K1=None, K2=None):
    """Su–Müller–Zheng observer for ``robot`` (docs/papers/seed002.md §3.3)  [S002 (35)] (only its size and joint
    names are used).

    Parameters
    ----------
    robot : models.RobotModel
        n joints.
    form : {"literal", "xian"}
        The printed (35) or the Xian form [DERIVED] (the runtime parameter ``xian``).
    smoothing_eps : float, optional
        sg = tanh(e / smoothing_eps) (rad); None or 0: the literal sign.
    K0, K1, K2 : (n,) array_like or float, optional
        Gains per joint (scalars broadcast): K0 (rad/s^2), K1 (1/s), K2 (1/s^2); defaults
        500, 10, 2000 (seed 002 §V-B).

    Returns
    -------
    codegen.core.spec.ObserverSpec
        Family ``su_nonsmooth``, vectors as in the module docstring.
    """
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, got {form!r}")
    eps = 0.0 if smoothing_eps is None else float(smoothing_eps)
    if not eps >= 0:
        raise ValueError(f"smoothing_eps must be None or >= 0, got {smoothing_eps!r}")
    n = robot.n
    K = {k: np.broadcast_to(np.asarray(SEED_GAINS[k] if v is None else v, float), (n,)).copy()
         for k, v in (("K0", K0), ("K1", K1), ("K2", K2))}
    x, y, u = ca.SX.sym("x", 2 * n), ca.SX.sym("y", n), ca.SX.sym("u", n)
    p = ca.SX.sym("p", 3 * n + 2)
    qhat, w = x[:n], x[n:]
    k0, k1, k2, xian, e_s = p[:n], p[n:2 * n], p[2 * n:3 * n], p[3 * n], p[3 * n + 1]
    e = qhat - y
    qd_hat = w - xian * (k1 + 1) * e
    xdot = ca.vertcat(qd_hat, -k0 * sg(e, e_s) - k2 * e - (1 - xian) * (k1 + 1) * w)
    est = ca.vertcat(qd_hat, qhat)
    y0, est0 = ca.SX.sym("y0", n), ca.SX.sym("est0", 2 * n)
    qhat0 = est0[n:]
    x0 = ca.vertcat(qhat0, est0[:n] + xian * (k1 + 1) * (qhat0 - y0))
    j = robot.joint_names
    return ObserverSpec(
        family="su_nonsmooth", robot=robot,
        x_names=[f"qhat_{s}" for s in j] + [f"w_{s}" for s in j],
        y_names=[f"q_{s}" for s in j], u_names=[f"tau_{s}" for s in j],
        p_names=[f"{g}_{s}" for g in ("K0", "K1", "K2") for s in j] + ["xian", "sgn_eps"],
        est_names=[f"qd_hat_{s}" for s in j] + [f"qhat_{s}" for s in j],
        p_default=np.concatenate([K["K0"], K["K1"], K["K2"], [float(form == "xian"), eps]]),
        rhs=ca.Function("rhs", [x, y, u, p], [xdot]),
        output=ca.Function("output", [x, y, u, p], [est]),
        init=ca.Function("init", [y0, est0, p], [x0]),
        design={"form": form, "smoothing_eps": smoothing_eps},
        # cross-check inputs: qhat near q (both signs of e, half the draws inside the tanh
        # layer), w ~ N(0, 5^2); u is unused
        inputs=InputRanges(u="plain", x_scale=(0.5,) * n + (0.0,) * n, x_fine=1e-4,
                           x_about_y=tuple((f"qhat_{s}", f"q_{s}") for s in j),
                           x_normal=tuple((f"w_{s}", 0.0, 5.0) for s in j)),
    )

