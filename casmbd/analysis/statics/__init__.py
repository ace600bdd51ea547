"""Statics and linearisation: static equilibrium, resting contacts, the trust region, stability."""
