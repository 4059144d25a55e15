"""Offline reduction of a recorded session (thesis Chapter 4, then Chapter 6): a stage registry
(:mod:`offline.reduction.registry`), one module per stage (:mod:`offline.reduction.stages`), run as one loop
(:func:`offline.reduction.run.reduce_session`) over the session's stored raw readings, read-only.

Where to look: the session as read (:mod:`.session`), what every stage works with (:mod:`.context`), the estimates
collected (:mod:`.estimates`), what several stages read off a joint's run (:mod:`.joints`), the torques of a loading
step (:mod:`.torques`), the pose set's model and its error terms (:mod:`.pose_model`, :mod:`.pose_errors`).  The
reduction never sees an emulated session's truth: that is scored afterwards by :mod:`sim.emulate.truth`.
"""
