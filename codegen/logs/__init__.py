"""The input side: a recorded log as a measurement, not as truth (docs/architecture.md §1).

``recording`` (the log: t, q, tau[, qd][, qdm]), ``smoothing`` (zero-phase derivatives), ``reference``
(the offline velocity a log without truth is measured against) and ``identify`` (a log -> a model:
inertials and friction).
"""
