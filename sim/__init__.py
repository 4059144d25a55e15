"""Simulation and validation: the twin (a seeded robot that differs from its description), the emulated
instruments that speak the real wire protocols about it, and the withheld-effect validation of the
diagnosis.  Production code (acquisition, reduction, calibration core) never imports it for its results.
"""
