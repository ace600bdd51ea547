"""Forward dynamics: the simulator, its stepping, post-processing and build cache, the numeric
formulations' driver and the energy invariants."""
