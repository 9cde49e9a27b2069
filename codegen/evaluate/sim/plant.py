"""The true robot as a block: a spec with no measurement, input u, output the full state.

    rigid:    x = [q; qd],            xdot = [qd; FD(q, qd, tau)]     [S000 (1)]
    elastic:  x = [q1; q1'; q2; q2'], xdot = f(x) + G(x) u            [S004 (2.6)-(2.11)], sim/elastic_plant.py

It is emitted and compiled like any observer and integrated in C by RK4 with ``substeps``
sub-steps per sample, the input held over the sample (zero-order hold).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...core.spec import ObserverSpec
from ...core.target import Discretization
from .blocks import block


def state_space_spec(family, robot, x_names, u_names, xdot):
    """Spec of x' = xdot(x, u) with no measurement, no parameter, output x, init x0 = est0.

    Parameters
    ----------
    family : str
        Family name of the spec (and of its C symbols).
    robot : models.RobotModel or models.ElasticRobot
        The robot the spec belongs to.
    x_names, u_names : list of str
        State and input names (sizes nx, nu).
    xdot : callable
        (x (nx, 1) SX, u (nu, 1) SX) -> (nx, 1) SX.

    Returns
    -------
    codegen.core.spec.ObserverSpec
    """
    nx, nu = len(x_names), len(u_names)
    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    y, p, x0 = ca.SX.sym("y", 0), ca.SX.sym("p", 0), ca.SX.sym("x0", nx)
    return ObserverSpec(
        family=family, robot=robot, x_names=list(x_names), y_names=[], u_names=list(u_names),
        p_names=[], est_names=list(x_names), p_default=[],
        rhs=ca.Function("rhs", [x, y, u, p], [xdot(x, u)]),
        output=ca.Function("output", [x, y, u, p], [x]),
        init=ca.Function("init", [y, x0, p], [x0]))


def plant_spec(robot):
    """Rigid-robot plant: state [q; qd], input tau, output [q; qd]."""
    n = robot.n
    names = [f"q_{j}" for j in robot.joint_names] + [f"qd_{j}" for j in robot.joint_names]
    return state_space_spec(
        "plant", robot, names, [f"tau_{j}" for j in robot.joint_names],
        lambda x, tau: ca.vertcat(x[n:], robot.forward_dynamics(x[:n], x[n:], tau)))


class SampledPlant:
    """A state-space spec compiled with RK4 sub-steps: ``reset_state(x0)``, ``advance(u) -> x``,
    ``state``."""

    def __init__(self, spec, dt, substeps, out_dir=None):
        self.dt, self.substeps, self.nx = dt, substeps, spec.nx
        disc = Discretization(dt=dt, method="rk4", hold="zoh", substeps=substeps)
        self.block = block(spec, disc, out_dir=out_dir)       # always C, also for reference runs
        self._empty = np.zeros(0)

    def reset_state(self, x0):
        """Start from the state ``x0`` (nx,)."""
        self.block.reset(self._empty, est0=np.asarray(x0, dtype=float))

    def advance(self, u):
        """Integrate over one sample with u held; returns the new state."""
        self.block.step(self._empty, u)
        return self.block.state

    @property
    def state(self):
        return self.block.state


class Plant(SampledPlant):
    """The true rigid robot integrated in C: ``reset(q0, qd0)``, ``advance(tau)``, ``state``."""

    def __init__(self, robot, dt, substeps=10, out_dir=None):
        self.robot, self.n = robot, robot.n
        super().__init__(plant_spec(robot), dt, substeps, out_dir)

    def reset(self, q0, qd0):
        """Start from joint positions ``q0`` (n,), rad, and velocities ``qd0`` (n,), rad/s."""
        self.reset_state(np.concatenate([q0, qd0]))
