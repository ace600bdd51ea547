"""The integrators: their kinds and registry, Dormand–Prince, the numeric right-hand-side bridge
to CVODES, the ranges of integrator options and the diagnosis of a failed integration."""
