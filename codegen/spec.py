"""ObserverSpec: a continuous-time observer as CasADi functions (DESIGN §1, §3).

Every observer family builds one of these; ``discretize``, ``emit``, ``build`` and
``runtime`` only ever see this shape, never a particular observer.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import casadi as ca
import numpy as np


@dataclass
class ObserverSpec:
    """A continuous-time observer (optionally hybrid).

    Flat float64 vectors with named slots:
      x  observer state          y  measurement        u  known input (torque)
      p  runtime parameters (gains, with designed defaults)
      est  the estimate the observer outputs

    Functions (casadi.Function):
      rhs(x, y, u, p)    -> xdot            the flow
      output(x, y, u, p) -> est             the estimate at the current sample
      init(y0, est0, p)  -> x0              state from a first measurement and an initial estimate
      jump(x, y, p)      -> x+   (or None)  hybrid jump map, applied before each step
    """

    family: str
    robot: object
    x_names: list
    y_names: list
    u_names: list
    p_names: list
    est_names: list
    p_default: np.ndarray
    rhs: ca.Function
    output: ca.Function
    init: ca.Function
    jump: ca.Function | None = None
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        self.p_default = np.asarray(self.p_default, dtype=float).reshape(-1)
        if self.p_default.size != len(self.p_names):
            raise ValueError(f"p_default has {self.p_default.size} entries, p_names {len(self.p_names)}")
        for f, ins, outs in ((self.rhs, (self.nx, self.ny, self.nu, self.np), (self.nx,)),
                             (self.output, (self.nx, self.ny, self.nu, self.np), (self.nest,)),
                             (self.init, (self.ny, self.nest, self.np), (self.nx,))):
            got_in = tuple(f.size1_in(i) * f.size2_in(i) for i in range(f.n_in()))
            got_out = tuple(f.size1_out(i) * f.size2_out(i) for i in range(f.n_out()))
            if got_in != ins or got_out != outs:
                raise ValueError(f"{self.family}: function {f.name()} has sizes {got_in}->{got_out}, "
                                 f"expected {ins}->{outs}")

    nx = property(lambda self: len(self.x_names))
    ny = property(lambda self: len(self.y_names))
    nu = property(lambda self: len(self.u_names))
    np = property(lambda self: len(self.p_names))
    nest = property(lambda self: len(self.est_names))

    @property
    def robot_source(self):
        """How the independent reference rebuilds the robot (see RobotModel.source)."""
        return self.robot.source

    @property
    def target_name(self):
        """Default target name, a C identifier: ``<robot>_<family>``."""
        return sanitize(f"{self.robot.name}_{self.family}")

    @property
    def params(self):
        """Default parameters as a name -> value dict."""
        return dict(zip(self.p_names, self.p_default.tolist()))


def sanitize(text):
    """A C identifier made from user data: lowercase, [a-z0-9_], not starting with a digit."""
    s = re.sub(r"[^0-9a-zA-Z_]", "_", str(text)).lower()
    s = re.sub(r"_+", "_", s).strip("_") or "x"
    return s if not s[0].isdigit() else "t_" + s
