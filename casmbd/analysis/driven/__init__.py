"""Analyses of a kinematically driven mechanism: kinematics and inverse dynamics."""
