"""Offline work on a saved session: the reduction of every procedure (:mod:`offline.reduction`) and the
report (HTML/PDF, terminal summary).  Reads the session store; never drives an instrument.
"""
