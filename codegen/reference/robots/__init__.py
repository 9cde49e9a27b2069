"""Reference robots rebuilt from a plain-data ``robot.source`` (numpy + pinocchio only).

The dispatcher on top of the robot modules; imports point one way:

    robots ──► rigid (closed forms), urdf (pinocchio), dh (Newton-Euler), elastic (docs/papers/seed004.md §6)
    elastic ──► dh ──► hyperdual;  urdf ──► rigid;  rigid, dh ──► friction ──► hyperdual

Never imports CasADi or the symbolic code (docs/architecture.md §1): written from the papers' equations (docs/papers/) so that
a cross-check against the generated C proves something.
"""
from __future__ import annotations

from .dh import DHRobot
from .elastic import ElasticRobot
from .rigid import Absolute2R, Planar2R
from .urdf import UrdfRobot

# docs/papers/experiments.md §11.1, §11.2, §12.3 numbers, kept here so tests can rebuild the seed robots
# without the symbolic catalog.
_SEED000 = dict(m1=10.0, m2=20.0, l1=1.0, l2=1.5)
_SEED002 = dict(m1=2.0, m2=1.0, l1=0.4, l2=0.2)
SEED_SOURCES = {
    "seed000_2r": {
        "kind": "closed_form", "name": "seed000_2r", "model": "planar_2r",
        "params": dict(_SEED000, lc1=0.5, lc2=0.75,
                       I1=10.0 * 1.0 ** 2 / 12, I2=20.0 * 1.5 ** 2 / 12,
                       g0=9.81, F=[0.1, 0.3]),                           # [S000 Table I]
    },
    "seed002_2r": {
        "kind": "closed_form", "name": "seed002_2r", "model": "planar_2r",
        "params": dict(_SEED002, lc1=0.2, lc2=0.1,
                       I1=2.0 * 0.4 ** 2 / 12, I2=1.0 * 0.2 ** 2 / 12,  # [ASSUMPTION] docs/papers/experiments.md §11.2
                       g0=9.81, F=[0.0, 0.0]),                           # [S002 §V]
    },
    "seed003_2r_abs": {
        "kind": "closed_form", "name": "seed003_2r_abs", "model": "absolute_2r",
        "params": dict(c1=0.9698, c2=0.1575, c3=0.264, c4=1.74, c5=0.44,
                       gravity_scale=1.0),                               # [S003 Table II], A3-2
    },
}

_CLOSED_FORMS = {"planar_2r": Planar2R, "absolute_2r": Absolute2R}
KINDS = ("closed_form", "urdf", "dh", "elastic")


def reference_robot(source):
    """The reference robot a ``robot.source`` dict describes.

    Parameters
    ----------
    source : dict
        One of
        ``{"kind": "closed_form", "model": "planar_2r" | "absolute_2r", "params": {...}}``,
        ``{"kind": "urdf", "path", "sha256", "locked_joints": {name: value}, "snap_tol"}``,
        ``{"kind": "dh", "dh", "masses", "coms", "inertias", "gravity", "F"}`` (reference/dh.py),
        ``{"kind": "elastic", "rigid": <source>, "J": (n,), "K": (n,)}`` (docs/papers/seed004.md §6);
        ``name`` optional in each; a rigid kind may carry ``"friction": {"viscous", "coulomb",
        "offset": (n,), "coulomb_width"}`` (reference/robots/friction.py), which replaces the
        description's friction (closed-form and DH "F", the URDF's damping and friction).

    Returns
    -------
    reference robot
        ``n``, ``M``, ``g``, ``F``, ``friction_torque``, ``nle``, ``forward_dynamics`` (and more
        per kind), with the dict kept as ``robot.source``.
    """
    if not isinstance(source, dict) or "kind" not in source:
        raise ValueError(f"robot source must be a dict with a 'kind' key, got {source!r}")
    kind = source["kind"]
    if kind == "closed_form":
        model = source.get("model")
        if model not in _CLOSED_FORMS:
            raise ValueError(f"unknown closed-form model {model!r} (expected one of {sorted(_CLOSED_FORMS)})")
        robot = _CLOSED_FORMS[model](source["params"], name=source.get("name", model))
    elif kind == "urdf":
        robot = UrdfRobot(source["path"], sha256=source.get("sha256"),
                          locked_joints=source.get("locked_joints") or {},
                          snap_tol=source.get("snap_tol", 1e-9))
    elif kind == "dh":
        robot = DHRobot(source)
    elif kind == "elastic":
        robot = ElasticRobot(reference_robot(source["rigid"]), source["J"], source["K"],
                             name=source.get("name", "elastic"))
    else:
        raise ValueError(f"unknown robot source kind {kind!r} (expected one of {KINDS})")
    if kind != "elastic":
        robot.set_friction(source.get("friction"))
    elif "friction" in source:
        raise ValueError("an elastic robot source carries its friction in its 'rigid' source")
    robot.source = dict(source)
    return robot
