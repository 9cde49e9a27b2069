"""Robot models: what a robot is (no observers here). See DESIGN §1-§3."""
from .catalog import load_robot, names
from .robot import ModelError, RobotModel

__all__ = ["load_robot", "names", "ModelError", "RobotModel"]
