"""Studies over many runs: parameter sweeps and sensitivities."""
