"""Sim-to-real gap diagnosis (issue 8): how far the measured robot is from the model, where, and why.

* :mod:`.data`        observations from a pose CSV (any robot: joint-name columns, units) or a session database's arrays;
* :mod:`.gap`         the geometric model fitted and scored on held-out poses, against the instruments' noise floor;
* :mod:`.breakdown`   the held-out residuals by joint angle, workspace region, payload, direction, time, temperature;
* :mod:`.candidates`  the library of unmodelled effects (the model's own effects), per joint where they apply;
* :mod:`.select`      greedy forward selection: held-out score, nested F-test, identifiability guard;
* :mod:`.validate`    the withheld-effect study on twin data (confusion matrix, false alarms, shrink);
* :mod:`.render`      the terminal tables;
* :mod:`.report`      HTML report with PNG figures;
"""
from .data import DiagnosisData, from_arrays, load_data
from .engine import Diagnosis, diagnose

__all__ = ["DiagnosisData", "Diagnosis", "diagnose", "from_arrays", "load_data"]
