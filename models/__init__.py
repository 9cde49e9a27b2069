"""Robot models: what a robot is (no observers here). See docs/architecture.md §1-§3."""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")     # one BLAS thread, before numpy loads (codegen/__init__.py)

from models.catalog import from_source, load_robot, names  # noqa: E402
from models.robot import ModelError, RobotModel  # noqa: E402

__all__ = ["from_source", "load_robot", "names", "ModelError", "RobotModel"]
