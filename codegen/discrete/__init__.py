"""The discrete-time observer: the step of a continuous-time spec (discretize), its stability
check (stability) and the working points both draw (sampling)."""
