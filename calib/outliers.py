"""Gross errors: which poses to flag, and which (if any) to leave out -- one implementation for identify and diagnose.

Why not simply drop every pose with a large residual: on real data the poses that stand out are often not blunders
but a systematic effect the model lacks (the same end-of-sweep poses for every reflector, every pose at the top of a
lifting column).  Dropping them hides the physics and makes held-out predictions worse.  So:

* a pose is **flagged** when its whitened residual is implausible against the others (chi-square at
  :data:`GROSS_P`, on a robust scale: an incomplete model inflates every residual alike, a blunder stands out);
* the flagged poses are tested for a **cluster** in each pose condition -- a joint angle (configuration), time or
  measurement order, payload, station or any other label.  A cluster is a systematic effect: the poses are kept and
  the report says where they cluster, so the diagnosis can look at it;
* mode ``flag`` (the default) reports and keeps; ``reject`` leaves out only unclustered flagged poses (blunders);
  ``off`` does neither.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .distributions import chi2_isf, chi2_median
from .errors import RobocalError
from .names import joint_label

OUTLIER_MODES = ("flag", "reject", "off")
#: scipy least_squares losses offered for the final fit (linear: plain least squares)
LOSSES = ("linear", "huber", "cauchy", "soft_l1")
#: per-pose probability below which a residual is called a gross error
GROSS_P = 1e-4
#: family-wise level at which the flagged poses are called clustered in a condition
CLUSTER_ALPHA = 0.01
#: more than this share of poses flagged is not a handful of blunders but a model that misses something
SYSTEMATIC_SHARE = 0.1


#: what the pose numbers of the JSON mean (identify and diagnose alike; docs/user-guide.md, "Identification")
NUMBERING = ("row: 1-based data row of the file as printed (header, unit and comment lines not counted); "
             "pose_id: the file's pose column, null without one")


@dataclass
class OutlierReport:
    mode: str
    flagged: list[int] = field(default_factory=list)      # 0-based poses with an implausible residual
    rejected: list[int] = field(default_factory=list)     # left out of the fit (reject mode, no cluster)
    cluster: str = ""              # why the flagged poses look systematic ("cluster in joint 3"; "" blunders)
    #: per fitted pose: its 1-based data row in the file (empty: the pose index + 1) and the file's pose id (empty:
    #: none); set by the caller that knows the file (:meth:`numbered`), so every reader sees the file's numbering
    rows: list[int] = field(default_factory=list)
    pose_ids: list[str] = field(default_factory=list)

    def numbered(self, rows=None, pose_ids=None) -> "OutlierReport":
        """This report with the file's numbering of the fitted poses (data rows, pose ids)."""
        self.rows = [int(r) for r in rows] if rows is not None else []
        self.pose_ids = [str(p) for p in pose_ids] if pose_ids else []
        return self

    def row(self, i: int) -> int:
        return self.rows[i] if self.rows else i + 1

    def name(self, i: int) -> str:
        """How the terminal names pose ``i``: the file's pose id where it has them, else its data row."""
        return self.pose_ids[i] if self.pose_ids else str(self.row(i))

    def poses(self) -> list[dict]:
        """The flagged poses as objects, each once: ``row`` (1-based data row), ``pose_id``, ``rejected``."""
        out: dict[int, dict] = {}
        rejected = set(self.rejected)
        for i in self.flagged:
            d = out.setdefault(self.row(i), {"row": self.row(i),
                                             "pose_id": self.pose_ids[i] if self.pose_ids else None,
                                             "rejected": False})
            d["rejected"] = d["rejected"] or i in rejected
        return list(out.values())

    def as_dict(self) -> dict:
        """JSON form: ``flagged``/``rejected`` as 1-based data rows (as the terminal counts them), ``poses`` the
        same as objects with the file's pose ids, ``numbering`` what the numbers mean."""
        return {"mode": self.mode, "flagged": sorted({self.row(i) for i in self.flagged}),
                "rejected": sorted({self.row(i) for i in self.rejected}), "cluster": self.cluster or None,
                "poses": self.poses(), "numbering": NUMBERING}

    def lines(self) -> list[str]:
        """What the terminal says (nothing when nothing was flagged)."""
        if not self.flagged:
            return []
        poses = ", ".join(dict.fromkeys(self.name(i) for i in self.flagged))
        if self.cluster:
            return [f"poses {poses} have implausible residuals, but they {self.cluster}: a systematic effect, not "
                    f"blunders -- kept"]
        if self.rejected:
            return [f"gross errors flagged and left out: poses {poses}"]
        return [f"gross errors flagged (kept; --outliers reject leaves them out): poses {poses}"]


def check_mode(mode: str, loss: str = "linear") -> str:
    if mode not in OUTLIER_MODES:
        raise RobocalError(f"--outliers must be one of {', '.join(OUTLIER_MODES)}, got {mode!r}")
    if loss not in LOSSES:
        raise RobocalError(f"--loss must be one of {', '.join(LOSSES)}, got {loss!r}")
    return mode


def flag_poses(chi2_per_pose: np.ndarray, dof_per_pose: int) -> list[int]:
    """Poses whose whitened residual sum of squares is implausible at :data:`GROSS_P` on a robust scale."""
    chi = np.asarray(chi2_per_pose, float)
    scale = max(1.0, float(np.median(chi) / chi2_median(dof_per_pose)))
    limit = chi2_isf(GROSS_P, dof_per_pose) * scale
    return [int(i) for i in np.flatnonzero(chi > limit)]


def pose_conditions(q_rad: np.ndarray, ctx=None, labels: dict[str, list] | None = None,
                    robot=None) -> dict[str, np.ndarray]:
    """The conditions a systematic effect could follow: each joint (named as :mod:`calib.names` shows it), time
    (else the measurement order), payload, temperature, and any per-pose labels (station, target, procedure)."""
    q = np.atleast_2d(q_rad)
    out: dict[str, np.ndarray] = {}
    for j in range(q.shape[1]):
        out[joint_label(robot, j + 1) if robot is not None else f"joint {j + 1}"] = q[:, j]
    t = getattr(ctx, "time_s", None)
    out["time" if t is not None and np.ptp(t) > 0 else "measurement order"] = (
        t if t is not None and np.ptp(t) > 0 else np.arange(len(q), dtype=float))
    for name, attr in (("payload", "payload_kg"), ("temperature", "temperature_c")):
        v = getattr(ctx, attr, None)
        if v is not None and np.ptp(v) > 0:
            out[name] = v
    for name, vals in (labels or {}).items():
        out[name] = np.asarray([str(v) for v in vals], dtype=object)
    return out


def _cluster_p(values: np.ndarray, flagged: np.ndarray) -> float:
    """How unlikely the flagged poses' values are under random choice: rank-sum for numbers, the hypergeometric
    tail of the most-hit group for labels."""
    # calib.distributions, not scipy.stats: importing that took 0.5-1 s of a 400-pose diagnosis
    from .distributions import hypergeom_sf, mann_whitney_p

    if values.dtype == object:
        groups, inv = np.unique(values, return_inverse=True)
        if len(groups) < 2:
            return 1.0
        hits = np.bincount(inv[flagged], minlength=len(groups))
        g = int(np.argmax(hits))
        size = int(np.sum(inv == g))
        return hypergeom_sf(int(hits[g]) - 1, len(values), size, int(flagged.sum()))
    if np.ptp(values) <= 0:
        return 1.0
    try:
        return mann_whitney_p(values[flagged], values[~flagged])
    except ValueError:
        return 1.0


def find_cluster(flagged: list[int], n_poses: int, conditions: dict[str, np.ndarray]) -> str:
    """Why the flagged poses look systematic: "cluster in <condition>" or "are too many ..." ("" when they look
    like independent blunders)."""
    k = len(flagged)
    if k == 0:
        return ""
    if k > max(2, SYSTEMATIC_SHARE * n_poses):
        return f"are too many for blunders ({k} of {n_poses} poses)"
    if k < 2:
        return ""
    mask = np.zeros(n_poses, bool)
    mask[flagged] = True
    best, where = 1.0, ""
    for name, vals in conditions.items():
        p = _cluster_p(np.asarray(vals), mask)
        if p < best:
            best, where = p, name
    return f"cluster in {where}" if best * len(conditions) < CLUSTER_ALPHA else ""


def decide(mode: str, chi2_per_pose: np.ndarray, dof_per_pose: int,
           conditions: dict[str, np.ndarray]) -> OutlierReport:
    """Flag, look for a cluster, and decide which poses (if any) to leave out."""
    check_mode(mode)
    if mode == "off":
        return OutlierReport(mode)
    flagged = flag_poses(chi2_per_pose, dof_per_pose)
    cluster = find_cluster(flagged, len(chi2_per_pose), conditions)
    rejected = list(flagged) if mode == "reject" and not cluster else []
    return OutlierReport(mode, flagged, rejected, cluster)
