"""The input side: a recorded log as a measurement, not as truth (docs/architecture.md §1).

``recording`` (the log: t, q, tau, optionally qd and qdm), ``mapping`` (a log's own column names
onto those), ``bag`` (a ROS bag's JointState topic as a log's columns), ``clock`` (what its time column is: a logger's
receive times rebuilt on the robot's tick), ``noise`` (its resolution, noise, motion band and
torque residual, measured), ``smoothing`` (zero-phase derivatives), ``reference`` (the offline
velocity a log without truth is measured against), ``identify`` (a log -> a model: inertials and
friction) and ``tune`` (a log -> gains, without truth: forward validation).
"""
