"""Analyses: they use the compiled model; the model never imports them."""
