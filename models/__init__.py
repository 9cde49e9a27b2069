"""Robot models: what a robot is (no observers here). See docs/architecture.md §1-§3."""
from models.catalog import from_source, load_robot, names
from models.robot import ModelError, RobotModel

__all__ = ["from_source", "load_robot", "names", "ModelError", "RobotModel"]
