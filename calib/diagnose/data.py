"""What the diagnosis reads: joint readings, measured points with their uncertainty, and the pose conditions.

Every source (a pose-measurement CSV in any of its column conventions, or the plain arrays the session layer hands
over for a session database) is turned into one :class:`DiagnosisData`, so the gap, breakdown and selection code
never looks at file formats.

Why the context flags matter: a candidate effect can only be tested when the data carries what drives it (approach
directions for backlash, temperature for thermal drift, varied load for compliance).  :attr:`DiagnosisData.has`
records which drivers were *measured* (a column present and not constant), so the candidate library can skip the
rest with a note instead of fitting a column of zeros.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calib.effects import PoseContext
from calib.errors import RobocalError
from calib.identify import PointObservations, whitening
from calib.loading import load_robot
from calib.model import MeasurementModel
from calib.noise import Sightings
from calib.orientation import dropped_note
from calib.posecsv import read_pose_csv
from calib.robot import Robot
from calib.targets import TargetContext, target_index, with_targets

SQLITE_MAGIC = b"SQLite format 3\x00"


@dataclass
class DiagnosisData:
    """Observations for diagnosis, in internal units (mm, rad; mm for a prismatic joint)."""

    robot: Robot
    q_rad: np.ndarray                      # (N, n) joint readings
    points_mm: np.ndarray                  # (N, 3) measured tool-target positions
    cov_mm2: np.ndarray                    # (N, 3, 3) their covariance (from the instruments or --noise-mm)
    ctx: PoseContext
    source: str = "<memory>"
    noise_from: str = "data"               # "data" (per-point covariance) or "--noise-mm"
    has: dict[str, bool] = field(default_factory=dict)       # direction, temperature, time, payload
    labels: dict[str, list[str]] = field(default_factory=dict)    # categorical per pose (sessions: procedure)
    numeric: dict[str, np.ndarray] = field(default_factory=dict)  # extra per-pose numbers (sighting angle, deg)
    raw_angles: bool = False               # theodolite readings available (instrument-error candidates)
    pose_id: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    split: list[str] | None = None         # the data's own "fit"/"test" split (else the diagnosis makes folds)
    ignored_columns: list[str] = field(default_factory=list)   # the file's columns not read (q7 of a 7-joint robot)
    sightings: Sightings | None = None     # raw readings behind each point (both faces: the noise estimate)
    #: the geometry beyond the chain every fit of the diagnosis carries: a tool point per extra target (an offset
    #: effect each, from :func:`calib.targets.with_targets`, as identify fits them), empty for one target
    geometry_effects: list = field(default_factory=list)
    direction_note: str = ""               # how the approach directions were inferred (empty: given, or none)

    @property
    def n(self) -> int:
        return len(self.q_rad)

    def model(self, effects=()) -> MeasurementModel:
        """The measurement model of this data: the robot, the data's own geometry effects, then ``effects``."""
        return MeasurementModel(self.robot, list(self.geometry_effects) + list(effects))

    def observations(self, idx=None) -> PointObservations:
        """The points as :class:`calib.identify.PointObservations` (all poses or a subset)."""
        if idx is None:
            return PointObservations(self.q_rad, self.points_mm, self.cov_mm2, ctx=self.ctx, white=self.whitening)
        idx = np.asarray(idx)
        return PointObservations(self.q_rad[idx], self.points_mm[idx], self.cov_mm2[idx],
                                 ctx=self.ctx.subset(idx) if self.ctx is not None else None, white=self.whitening[idx])

    def subset(self, idx) -> "DiagnosisData":
        """The same data on the poses ``idx`` (conditions, labels and ids follow)."""
        idx = np.asarray(idx)
        out = DiagnosisData(self.robot, self.q_rad[idx], self.points_mm[idx], self.cov_mm2[idx],
                            self.ctx.subset(idx), self.source, self.noise_from, dict(self.has),
                            {k: [v[i] for i in idx] for k, v in self.labels.items()},
                            {k: np.asarray(v)[idx] for k, v in self.numeric.items()}, self.raw_angles,
                            [self.pose_id[i] for i in idx] if self.pose_id else [], list(self.notes),
                            [self.split[i] for i in idx] if self.split else None,
                            list(self.ignored_columns),
                            sightings=self.sightings.subset(idx) if self.sightings is not None else None,
                            geometry_effects=list(self.geometry_effects), direction_note=self.direction_note)
        W = self.whitening[idx]                  # the same rows of this set's whitening (computed row by row)
        W.flags.writeable = False
        out.__dict__["_whitening"] = (out.cov_mm2, W)
        return out

    def joint_name(self, joint: int | None) -> str | None:
        """The description's name of a 1-based joint (a URDF's joint name; the DH table's names otherwise)."""
        if joint is None:
            return None
        names = self.robot.description_joint_names or self.robot.joint_names
        return str(names[joint - 1]) if names and 1 <= joint <= len(names) else f"j{joint}"

    @property
    def whitening(self) -> np.ndarray:
        """(N, 3, 3) W with W^T W = cov^-1: whitened residual = W r (:func:`calib.identify.whitening`, computed once
        for this covariance array: every fold fit and score of a diagnosis asks for it)."""
        cached = self.__dict__.get("_whitening")
        if cached is None or cached[0] is not self.cov_mm2:
            W = whitening(self.cov_mm2)
            W.flags.writeable = False           # shared by every caller: read-only
            cached = self.__dict__["_whitening"] = (self.cov_mm2, W)
        return cached[1]


def _varies(a: np.ndarray | None) -> bool:
    return a is not None and np.size(a) > 0 and bool(np.ptp(np.asarray(a, float), axis=0).max() > 0)


def from_arrays(robot: Robot, q_rad, points_mm, cov_mm2=None, noise_mm: float | None = None, *, direction=None,
                payload_kg=None, temperature_c=None, time_s=None, source: str = "<memory>",
                pose_id=None, target: list[str] | None = None) -> DiagnosisData:
    """Build :class:`DiagnosisData`; the covariance comes from ``cov_mm2`` or, failing that, ``noise_mm``.
    ``target``: per row the tool point it measures (several targets per pose): each target is its own tool point
    on the flange, fitted jointly with the chain as identify does (:func:`calib.targets.with_targets`)."""
    q = np.atleast_2d(np.asarray(q_rad, float))
    p = np.atleast_2d(np.asarray(points_mm, float))
    N = len(q)
    if q.shape[1] != robot.n:
        raise RobocalError(f"{source}: {q.shape[1]} joint columns but the robot {robot.name!r} has {robot.n} joints")
    if p.shape != (N, 3):
        raise RobocalError(f"{source}: {N} poses but {len(p)} measured points")
    noise_from = "data"
    if cov_mm2 is None:
        if noise_mm is None:
            raise RobocalError(f"{source}: the data carries no per-point uncertainty (no sigma_x_mm.. columns); "
                               f"give the 1-sigma noise per coordinate with --noise-mm")
        if not noise_mm > 0:
            raise RobocalError(f"--noise-mm must be positive, got {noise_mm}")
        cov_mm2 = np.broadcast_to(np.eye(3) * noise_mm ** 2, (N, 3, 3)).copy()
        noise_from = "--noise-mm"
    cov_mm2 = np.asarray(cov_mm2, float)
    if N < 8:
        raise RobocalError(f"{source}: {N} poses are too few to diagnose (need at least 8 for a held-out test)")
    conditions = dict(direction=direction, payload_kg=payload_kg, temperature_c=temperature_c, time_s=time_s)
    geometry: list = []
    if target is None:
        ctx = PoseContext(N, robot.n, **conditions)
    else:
        robot, geometry, ctx = _targets(robot, [str(t) for t in target], N, source, conditions)
    has = {"direction": direction is not None and bool(np.any(np.asarray(direction) != 0)),
           "temperature": _varies(temperature_c), "time": _varies(time_s), "payload": _varies(payload_kg)}
    d = DiagnosisData(robot, q, p, cov_mm2, ctx, source, noise_from, has,
                      pose_id=list(pose_id) if pose_id is not None else [], geometry_effects=geometry)
    if target is not None:                  # the noise estimate reads the targets' distances per pose
        d.labels["target"] = [str(t) for t in target]
    return d


def _targets(robot: Robot, target: list[str], n: int, source: str, conditions: dict):
    """The robot with a tool point per target (reference first), the other targets' offset effects and the pose
    context that says which tool point each row measures."""
    if len(target) != n:
        raise RobocalError(f"{source}: {n} rows but {len(target)} target labels")
    unknown = sorted(set(target) - set(robot.tool_points_mm))
    if unknown:
        raise RobocalError(f"{source}: target {unknown[0]!r} names no tool point of {robot.name!r} (tool points: "
                           f"{', '.join(robot.tool_points_mm) or 'none'})")
    robot, geometry = with_targets(robot, list(dict.fromkeys(target)))
    return robot, geometry, TargetContext(n, robot.n, **conditions, target=target_index(robot, target, n))


def is_session_db(path: str | Path) -> bool:
    try:
        with open(path, "rb") as fh:
            return fh.read(16) == SQLITE_MAGIC
    except OSError:
        return False


def from_session_arrays(robot: Robot, arrays: dict, source: str) -> DiagnosisData:
    """A session database's pose set, as the session layer hands it over (plain arrays; ``calib`` never reads the
    session store itself, data flow one way): ``q_rad`` (N, n), ``points_mm`` (N, 3), ``cov_mm2`` (N, 3, 3),
    optional ``direction``, ``payload_kg``, ``temperature_c``, ``time_s``, ``procedure`` (N step procedure names),
    ``sighting_angle_deg`` (N,) (intersection angle of the two sight lines), ``raw_angles`` (bool), and, as a pose
    CSV gives them, ``pose`` ids, ``station`` and ``target`` labels and the data's own ``split``; when the points were
    intersected from raw readings, ``readings`` (per pose the reading dicts), ``readings_target`` (per pose the
    target those readings sight) and ``stations`` (name -> Station): the both-faces noise estimate reads them."""
    d = from_arrays(robot, arrays["q_rad"], arrays["points_mm"], arrays.get("cov_mm2"), None,
                    direction=arrays.get("direction"), payload_kg=arrays.get("payload_kg"),
                    temperature_c=arrays.get("temperature_c"), time_s=arrays.get("time_s"), source=source,
                    pose_id=arrays.get("pose"))
    for name in ("procedure", "station", "target"):
        if arrays.get(name) is not None:
            d.labels[name] = [str(s) for s in arrays[name]]
    if arrays.get("split") is not None:
        d.split = [str(s) for s in arrays["split"]]
    if arrays.get("sighting_angle_deg") is not None:
        d.numeric["sighting angle (deg)"] = np.asarray(arrays["sighting_angle_deg"], float)
    d.raw_angles = bool(arrays.get("raw_angles", False))
    if arrays.get("readings") is not None and arrays.get("stations"):
        d.sightings = Sightings(list(arrays["readings"]), list(arrays["readings_target"]), dict(arrays["stations"]))
    return d


def load_data(path: str | Path, robot: Robot | None = None, noise_mm: float | None = None, *,
              angle_unit: str | None = None, length_unit: str | None = None, order: str = "none",
              time_column: str | None = None, direction_threshold: tuple[float, float] | None = None) -> DiagnosisData:
    """Read DATA: a pose-measurement CSV (units: see :func:`calib.posecsv.read_pose_csv`).  (Session databases come
    through the session layer as arrays: :func:`from_session_arrays`.)  ``order``, ``time_column``,
    ``direction_threshold``: approach directions from the measurement order (:mod:`calib.approach`); how they were
    inferred is a note of the data."""
    path = Path(path)
    if not path.exists():
        raise RobocalError(f"{path}: file not found")
    if is_session_db(path):
        raise RobocalError(f"{path}: a session database reaches the diagnosis through the session layer "
                           f"(robocal diagnose reads it); load_data reads pose CSVs")
    robot = robot or load_robot()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = read_pose_csv(path, robot.n, robot.prismatic, robot=robot, angle_unit=angle_unit,
                              length_unit=length_unit, order=order, time_column=time_column,
                              direction_threshold=direction_threshold)
    if table.points_mm is None:
        raise RobocalError(f"{path}: columns x, y, z (measured tool points, mm) are needed to diagnose")
    cov = None
    if table.sigma_mm is not None:
        cov = np.einsum("ni,ij->nij", table.sigma_mm ** 2, np.eye(3))
    d = from_arrays(robot, table.q_rad, table.points_mm, cov, noise_mm,
                    direction=table.direction, payload_kg=table.payload_kg, temperature_c=table.temperature_c,
                    time_s=table.time_s, source=str(path), pose_id=table.pose_id or None, target=table.target)
    if getattr(table, "station", None):
        d.labels["station"] = list(table.station)
    if getattr(table, "split", None):
        d.split = list(table.split)
    d.ignored_columns = [str(c) for c in getattr(table, "ignored_columns", None) or ()]
    d.notes += [str(w.message) for w in caught]
    if table.orientation_rad is not None:
        d.notes.append(dropped_note(path))
    if table.direction_note:
        d.notes.append(table.direction_note)
        d.direction_note = table.direction_note
    return d
