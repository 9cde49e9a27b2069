"""Values every layer shares: Target and Discretization, typed options, the ObserverSpec, the
symbolic helpers, recordings (CSV), the on-disk cache and atomic writes, the version."""
