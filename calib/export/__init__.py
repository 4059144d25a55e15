"""What leaves a calibration for other software: a calibrated URDF (:mod:`calib.export.urdf_out`), the side file of
what a URDF cannot hold (:mod:`calib.export.side`) and per-joint DH deltas for controllers (:mod:`calib.export.
dh_deltas`).  Every export is built from the model's frames (:mod:`calib.export.frames`), not from DH formulas."""
