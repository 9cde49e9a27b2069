"""The true elastic-joint robot as a compiled block (SPEC §6): x = [q1; q1'; q2; q2'] (4n),
x' = f(x) + G u, integrated in C by RK4 with ``substeps`` sub-steps per sample, u held over
the sample (zero-order hold). Same pattern as sim/plant.py (a spec with no measurement).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..spec import ObserverSpec


def elastic_plant_spec(robot):
    """Elastic plant: state x (4n), input u (n), output x."""
    x, u = ca.SX.sym("x", robot.nx), ca.SX.sym("u", robot.n)
    y, p = ca.SX.sym("y", 0), ca.SX.sym("p", 0)
    x0 = ca.SX.sym("x0", robot.nx)
    return ObserverSpec(
        family="elastic_plant", robot=robot, x_names=list(robot.state_names), y_names=[],
        u_names=[f"u_{j}" for j in robot.joint_names], p_names=[], est_names=list(robot.state_names),
        p_default=[],
        rhs=ca.Function("rhs", [x, y, u, p], [ca.cse(robot.dynamics(x, u))]),
        output=ca.Function("output", [x, y, u, p], [x]),
        init=ca.Function("init", [y, x0, p], [x0]))


class ElasticPlant:
    """``reset(x0)``, ``advance(u) -> x``, ``state``; ``n`` joints, ``nx = 4n``."""

    def __init__(self, robot, dt, substeps=2, out_dir=None):
        from .. import compile_observer
        self.robot, self.n, self.nx, self.dt, self.substeps = robot, robot.n, robot.nx, dt, substeps
        self.block = compile_observer(elastic_plant_spec(robot), dt=dt, method="rk4",
                                      substeps=substeps, out_dir=out_dir)
        self._empty = np.zeros(0)

    def reset(self, x0):
        self.block.reset(self._empty, est0=np.asarray(x0, dtype=float))

    def advance(self, u):
        """Integrate over one sample with u held; returns the new state."""
        self.block.step(self._empty, u)
        return self.block.state

    @property
    def state(self):
        return self.block.state
