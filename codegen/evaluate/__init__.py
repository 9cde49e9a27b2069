"""How good an estimate is: baselines a user would write, metrics, simulated plants (sim/), the
papers' experiments (scenarios/), comparisons, sweeps and benchmarks."""
