"""Bytes: a Target (targets_file) through design, emit (C from templates/), compile (gcc, cached
by content) and load (ctypes); stages runs them in one sequence."""
