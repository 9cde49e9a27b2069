"""The true robot as a block: x = [q; qd], xdot = [qd; FD(q, qd, tau)]  [S000 (1)].

The plant is a spec like any observer (no measurement, input tau, output the full state),
so it is emitted and compiled the same way and integrated in C by RK4 with `substeps`
sub-steps per sample, the torque held over the sample (zero-order hold).
"""
from __future__ import annotations

import casadi as ca

from ..spec import ObserverSpec


def plant_spec(robot):
    """Rigid-robot plant: state [q; qd], input tau, output [q; qd]."""
    n = robot.n
    x, tau = ca.SX.sym("x", 2 * n), ca.SX.sym("tau", n)
    y, p = ca.SX.sym("y", 0), ca.SX.sym("p", 0)
    q, v = x[:n], x[n:]
    xdot = ca.vertcat(v, robot.forward_dynamics(q, v, tau))
    names = [f"q_{j}" for j in robot.joint_names] + [f"qd_{j}" for j in robot.joint_names]
    x0 = ca.SX.sym("x0", 2 * n)
    return ObserverSpec(
        family="plant", robot=robot, x_names=names, y_names=[],
        u_names=[f"tau_{j}" for j in robot.joint_names], p_names=[], est_names=names, p_default=[],
        rhs=ca.Function("rhs", [x, y, tau, p], [xdot]),
        output=ca.Function("output", [x, y, tau, p], [x]),
        init=ca.Function("init", [y, x0, p], [x0]))


class Plant:
    """The true robot integrated in C: ``reset(q0, qd0)``, ``advance(tau)``, ``q``, ``qd``."""

    def __init__(self, robot, dt, substeps=10, out_dir=None):
        from .. import compile_observer
        self.robot, self.n, self.dt, self.substeps = robot, robot.n, dt, substeps
        self.block = compile_observer(plant_spec(robot), dt=dt, method="rk4", substeps=substeps,
                                      out_dir=out_dir)
        self._empty = []

    def reset(self, q0, qd0):
        import numpy as np
        self.block.reset(self._empty, est0=np.concatenate([q0, qd0]))

    def advance(self, tau):
        """Integrate over one sample with tau held; returns the new [q; qd]."""
        self.block.step(self._empty, tau)
        return self.block.state

    @property
    def state(self):
        return self.block.state
