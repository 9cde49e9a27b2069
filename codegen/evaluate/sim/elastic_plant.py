"""The true elastic-joint robot as a compiled block (docs/papers/seed004.md §6): x = [q1; q1'; q2; q2'] (4n),
x' = f(x) + G u, integrated in C by RK4 with ``substeps`` sub-steps per sample, u held over
the sample (zero-order hold); see sim/plant.py.
"""
from __future__ import annotations

import casadi as ca

from .plant import SampledPlant, state_space_spec


def elastic_plant_spec(robot):
    """Elastic plant of the ``models.ElasticRobot`` ``robot``: state x (4n), input u (n, N m),
    output x; x' = f(x) + G u  [S004 (2.8)-(2.11)]."""
    return state_space_spec("elastic_plant", robot, robot.state_names,
                            [f"u_{j}" for j in robot.joint_names],
                            lambda x, u: ca.cse(robot.dynamics(x, u)))


class ElasticPlant(SampledPlant):
    """``reset(x0)``, ``advance(u) -> x``, ``state``; ``n`` joints, ``nx = 4n``."""

    def __init__(self, robot, dt, substeps=2, out_dir=None):
        self.robot, self.n = robot, robot.n
        super().__init__(elastic_plant_spec(robot), dt, substeps, out_dir)

    def reset(self, x0):
        """Start from the state ``x0`` = [q1; q1'; q2; q2'] (4n,), rad and rad/s."""
        self.reset_state(x0)
