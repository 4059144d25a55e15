"""The identified model as files, and its use: corrected joint readings and commands, predicted tool positions.

Two files leave an identification:

* a robot description (TOML, :func:`calib.robot.robot_to_toml`) with the identified geometry — what other software
  can read;
* a model JSON holding *every* parameter with its 1-sigma uncertainty and unit, the running-error terms (which a
  DH table cannot carry: transmission error, compliance, backlash, coupling, thermal) and the covariance, so that
  :func:`load_model` rebuilds the same :class:`MeasurementModel` for compensation.

Compensation generalises the thesis's eq 6.1 to additive running-error terms: the true joint angle is the reading
plus every joint-stage effect; a joint command is corrected so that the identified model reaches the point the
nominal model would have reached (minimum-norm Newton steps on the joint angles).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .effects import PoseContext, effect_from_spec, effect_spec
from .effects.station_offset import StationOffset
from .errors import RobocalError
from .fileio import atomic_write_text
from .identify import Identification
from .targets import identified_tool_points
from .jsonfile import FINITE, check_schema, read_json
from .model import MeasurementModel
from .names import joint_of, joint_name, unit_of
from .robot import Robot, parse_robot, robot_to_toml
from .units import DEG

FORMAT = "robocal-model/1"




def robot_from_theta(model: MeasurementModel, theta: np.ndarray) -> Robot:
    """The robot description with the geometric part of ``theta`` written into it (every target's tool point)."""
    kin = model.kin
    r = model.robot
    g = theta[: kin.P]

    def per_joint(key):
        return np.array([g[kin.index[f"j{j + 1}.{key}"]] for j in range(r.n)])

    base = [g[kin.index[f"base.{k}"]] for k in ("x_mm", "y_mm", "z_mm")]
    rpy = [g[kin.index["base.roll_rad"]], g[kin.index["base.pitch_rad"]], g[kin.index["base.yaw_rad"]]]
    return replace(r, a_mm=per_joint("a_mm"), d_mm=per_joint("d_mm"), alpha_rad=per_joint("alpha_rad"),
                   theta_offset_rad=per_joint("theta_offset_rad"), beta_rad=per_joint("beta_rad"),
                   base_xyz_mm=np.array(base), base_rpy_rad=np.array(rpy),
                   tool_points_mm=identified_tool_points(model, theta),
                   name=f"{r.name} (identified)")


def model_document(model: MeasurementModel, ident: Identification, truth: dict[str, float] | None = None,
                   provenance: dict | None = None, extra: dict | None = None) -> dict:
    """The model JSON: every parameter with value, error (1 sigma), unit and whether it was estimated; with
    ``provenance`` (:func:`calib.provenance.provenance`) under that key; ``extra`` keys added as they are
    (``located_nominal``: the "before" model's located parameters; ``prediction_noise``: what a new point carries on
    top of the parameters' error -- what ``robocal evaluate`` needs for the before/after figures and the predicted
    sigmas)."""
    P = model.P
    params = []
    for i, name in enumerate(ident.names):
        params.append({"name": name, "value": float(ident.theta[i]), "error": float(ident.sigma[i]),
                       "unit": unit_of(name), "estimated": name in ident.free,
                       "truth": None if truth is None or name not in truth else float(truth[name])})
        j = joint_of(name, model.robot.n)
        if j is not None:                    # the index stays in the name; the description's name beside it
            params[-1].update(joint=j, joint_name=joint_name(model.robot, j))
    free = [n for n in ident.free if n in model.index]
    idx = [model.index[n] for n in free]
    rep = ident.outlier_report
    return {
        "format": FORMAT,
        "robot_toml": robot_to_toml(robot_from_theta(model, ident.theta[:P])),
        "nominal_robot_toml": robot_to_toml(model.robot),
        "parameters": params,
        "effects": [effect_spec(e) for e in model.effects],
        **({"stations": model.stations} if model.stations is not None else {}),
        "covariance": {"names": free, "matrix": _symmetric(ident.cov[np.ix_(idx, idx)]).tolist()},
        "identifiability": ident.identifiability.report(model.robot),
        "residual_rms": ident.residual_rms,
        "reduced_chi2": ident.reduced_chi2,
        # the flagged poses as objects (row: 1-based data row, pose_id, rejected), as diagnose's outliers.poses;
        # outlier_report: the whole decision (mode, flagged/rejected rows, cluster), as diagnose's outliers
        "outliers": rep.poses() if rep is not None else [{"row": i + 1, "pose_id": None, "rejected": False}
                                                         for i in ident.outliers],
        **({"outlier_report": rep.as_dict()} if rep is not None else {}),
        **({"provenance": provenance} if provenance is not None else {}),
        **(extra or {}),
    }


def _symmetric(C: np.ndarray) -> np.ndarray:
    return 0.5 * (C + C.T)


def save_model(path: str | Path, model: MeasurementModel, ident: Identification,
               robot_toml: str | Path | None = None, truth: dict[str, float] | None = None,
               provenance: dict | None = None, extra: dict | None = None) -> dict:
    doc = model_document(model, ident, truth, provenance, extra)
    atomic_write_text(path, json.dumps(doc, indent=1))
    if robot_toml:
        atomic_write_text(robot_toml, doc["robot_toml"])
    return doc


@dataclass
class IdentifiedModel:
    model: MeasurementModel
    theta: np.ndarray
    cov: np.ndarray                 # (P, P) over the model's parameters, zeros where held
    nominal_robot: Robot            # the description the identification started from (what the controller uses)
    located_nominal: dict[str, float] | None = None   # the "before" model: every parameter (design values, located base,
                                                      # tool, targets and set-ups)
    prediction_noise: dict | None = None              # {"sigma_mm": used per coordinate, "scale": applied to it}

    def before_theta(self) -> np.ndarray | None:
        """The located nominal model's parameters (the description's geometry, the located values), or None when the
        file predates them."""
        if not self.located_nominal or any(n not in self.located_nominal for n in self.model.names):
            return None
        return np.array([self.located_nominal[n] for n in self.model.names], float)


#: the model JSON's structure (checked whole before anything is built from it)
MODEL_SCHEMA = {
    "type": "object",
    "required": ["format", "robot_toml", "nominal_robot_toml", "parameters", "effects", "covariance"],
    "properties": {
        "format": {"const": FORMAT},
        "robot_toml": {"type": "string", "maxLength": 1_000_000},
        "nominal_robot_toml": {"type": "string", "maxLength": 1_000_000},
        "parameters": {"type": "array", "maxItems": 100_000, "items": {
            "type": "object", "required": ["name", "value"],
            # +Infinity is a value some effects use for "none" (a compliance breakpoint); NaN and -Infinity are not
            "properties": {"name": {"type": "string", "minLength": 1},
                           "value": {"type": "number", "notNaN": True, "minimum": -1e30},
                           "error": {"type": ["number", "null"], "minimum": 0, "maximum": 1e12},
                           "estimated": {"type": "boolean"}}}},
        "effects": {"type": "array", "maxItems": 1000, "items": {
            "type": "object", "required": ["type"],
            "properties": {"type": {"type": "string"}, "joint": {"type": ["integer", "null"], "minimum": 1,
                                                                 "maximum": 64}},
            "additionalProperties": FINITE}},
        "stations": {"type": "array", "maxItems": 10000, "items": {"type": "string"}, "uniqueItems": True},
        "located_nominal": {"type": "object", "additionalProperties": {"type": "number", "notNaN": True,
                                                                       "minimum": -1e30}},
        "prediction_noise": {"type": "object", "properties": {"sigma_mm": {"type": "number", "minimum": 0},
                                                              "scale": {"type": "number", "minimum": 0}}},
        "covariance": {"type": "object", "required": ["names", "matrix"], "properties": {
            "names": {"type": "array", "items": {"type": "string"}, "uniqueItems": True},
            "matrix": {"type": "array", "items": {"type": "array", "items": FINITE}}}},
    },
}


#: largest magnitude a parameter of each unit can have in a robot model (an angle within two turns, a length within
#: a kilometre): anything beyond is a damaged value, however finite
PARAMETER_BOUNDS = {"rad": 4 * np.pi, "mm": 1e6}


def load_model(path: str | Path) -> IdentifiedModel:
    """Rebuild the identified model from its JSON.  The whole document is checked first (structure by
    :data:`MODEL_SCHEMA`, then the descriptions, the effects, the covariance and a trial prediction), so a damaged
    file is one line naming the key, never a crash deep in the arithmetic."""
    return model_from_document(read_json(path, allow_nonfinite=True), str(path))


def model_from_document(doc, src: str) -> IdentifiedModel:
    """The identified model from a model document already read (a model JSON, or the ``robot`` a reprocess
    returns), checked as :func:`load_model` checks a file; ``src`` names it in messages."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise RobocalError(f"{src}: not a robocal model file (format {FORMAT!r} expected)")
    check_schema(doc, MODEL_SCHEMA, src)
    robot = parse_robot(doc["robot_toml"], f"{src}: robot_toml")
    nominal_robot = parse_robot(doc["nominal_robot_toml"], f"{src}: nominal_robot_toml")
    if nominal_robot.n != robot.n:
        raise RobocalError(f"{src}: nominal_robot_toml has {nominal_robot.n} joints, robot_toml {robot.n}")
    values = {p["name"]: float(p["value"]) for p in doc["parameters"]}
    for i, (name, v) in enumerate(values.items()):
        bound = PARAMETER_BOUNDS.get(unit_of(name))
        if bound is not None and not abs(v) <= bound:
            raise RobocalError(f"{src}: parameters[{i}].value: {name} = {v:g} {unit_of(name)} is beyond "
                               f"+-{bound:g}: a damaged value")
    effects = []
    for i, spec in enumerate(doc["effects"]):
        where = f"{src}: effects[{i}]"
        if spec.get("joint") is not None and spec["joint"] > robot.n:
            raise RobocalError(f"{where}.joint: must be a joint number 1..{robot.n}, got {spec['joint']}")
        effects.append(effect_from_spec(spec, values, where))
    model = MeasurementModel(robot, effects, stations=doc.get("stations"))
    n_offsets = sum(isinstance(e, StationOffset) for e in effects)
    if model.stations is not None and n_offsets and n_offsets != len(model.stations) - 1:
        raise RobocalError(f"{src}: stations: {len(model.stations)} names for {n_offsets + 1} set-ups "
                           "(the reference and one station_offset effect each)")
    theta = model.nominal.copy()
    for i, name in enumerate(model.names):
        if name in values:
            theta[i] = values[name]
    cov = np.zeros((model.P, model.P))
    names = doc["covariance"]["names"]
    rows = doc["covariance"]["matrix"]
    unknown = [n for n in names if n not in model.index]
    if unknown:
        raise RobocalError(f"{src}: covariance.names: {unknown[0]!r} is not a parameter of the model")
    if len(rows) != len(names) or any(len(r) != len(names) for r in rows):
        raise RobocalError(f"{src}: covariance.matrix: must be {len(names)}x{len(names)} (one row and column per "
                           "name)")
    C = np.asarray(rows, float).reshape(len(names), len(names))
    # symmetric to the precision of its own diagonal (a solver's covariance carries rounding off the diagonal)
    scale = np.sqrt(np.outer(np.abs(np.diag(C)), np.abs(np.diag(C)))) + 1e-300
    if np.max(np.abs(C - C.T) / scale, initial=0.0) > 1e-6:
        raise RobocalError(f"{src}: covariance.matrix: is not symmetric")
    C = _symmetric(C)
    if len(names) and np.linalg.eigvalsh(C).min() < -1e-9 * max(1.0, float(np.abs(C).max())):
        raise RobocalError(f"{src}: covariance.matrix: is not positive semi-definite")
    idx = [model.index[n] for n in names]
    cov[np.ix_(idx, idx)] = C
    located = doc.get("located_nominal")
    noise = doc.get("prediction_noise")
    im = IdentifiedModel(model, theta, cov, nominal_robot,
                         {str(k): float(v) for k, v in located.items()} if isinstance(located, dict) else None,
                         noise if isinstance(noise, dict) else None)
    _trial_prediction(im, src)
    return im


def _trial_prediction(im: IdentifiedModel, src: str) -> None:
    """Parameters that are finite one by one can still make nonsense together (a compliance of 1e-300, a gear ratio
    that overflows): predict the tool point at the middle of the joint ranges and refuse a non-finite answer."""
    q = im.model.robot.limits_rad.mean(axis=1)[None, :]
    with np.errstate(all="ignore"):
        try:
            p, s = predict(im, q)
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as exc:
            raise RobocalError(f"{src}: the parameters give no prediction ({type(exc).__name__}: {exc})") from None
    if not (np.isfinite(p).all() and np.isfinite(s).all()) or np.abs(p).max() > 1e9:
        raise RobocalError(f"{src}: the parameters give a non-finite or absurd tool point: a damaged value")


def corrected_readings(im: IdentifiedModel, q_read_rad: np.ndarray, ctx: PoseContext | None = None) -> np.ndarray:
    """True joint angles for readings: eq 6.1 generalised (reading + every running-error term)."""
    return im.model.evaluate(q_read_rad, ctx, im.theta).theta_rad


def predict(im: IdentifiedModel, q_read_rad: np.ndarray, ctx: PoseContext | None = None):
    """Tool points (N, 3) and their 1-sigma uncertainty per coordinate from the parameter covariance."""
    ev = im.model.evaluate(q_read_rad, ctx, im.theta, jacobian=True)
    var = np.einsum("nip,pq,niq->ni", ev.jacobian, im.cov, ev.jacobian)
    return ev.point_mm, np.sqrt(np.clip(var, 0, None))


def compensate_command(im: IdentifiedModel, nominal: MeasurementModel, q_desired_rad: np.ndarray,
                       ctx: PoseContext | None = None, iterations: int = 10, tol_mm: float = 1e-6):
    """Joint commands that make the identified robot reach the points the nominal model gives for ``q_desired``.

    The nominal model must share the identified model's measurement frame (base) and tool, so that only the robot's
    own errors are compensated.  ``q_desired`` and the commands are joint variables (N, n); see
    :func:`compensate_readings` for a robot whose readings are not its joints.  Returns the commands and the
    remaining position error (N,) in mm (the largest over the robot's points)."""
    n = im.model.robot.n
    return compensate_readings(im, nominal, q_desired_rad, ctx, iterations, tol_mm, np.eye(n), np.zeros(n))


def compensate_readings(im: IdentifiedModel, nominal: MeasurementModel, r_desired: np.ndarray,
                        ctx: PoseContext | None = None, iterations: int = 10, tol_mm: float = 1e-6,
                        reading_matrix: np.ndarray | None = None, reading_offset: np.ndarray | None = None):
    """Controller readings (commands, N x m) that bring every tool point of the identified robot to where the
    nominal model puts it for ``r_desired``: one Gauss-Newton solve over all points together (a branched robot's
    hands share the torso's commands; a coupled or mimic joint follows its readings).  Returns the commands (N, m)
    and the remaining error (N,) in mm, the largest over the points."""
    robot = im.model.robot
    M = robot.reading_matrix if reading_matrix is None else reading_matrix
    off = robot.reading_offset if reading_offset is None else reading_offset
    r_des = np.atleast_2d(np.asarray(r_desired, float))
    points = points_to_compensate(im)
    q_des = r_des @ M.T + off
    target = np.stack([nominal.evaluate(q_des, None, None, tool_mm=xyz, link=f).point_mm for f, xyz in points], 1)
    r, err = reach(im.model, im.theta, points, target, r_des, M, off, ctx, iterations, tol_mm)
    q = r @ M.T + off
    lim = robot.limits_rad
    outside = np.any((q < lim[:, 0] - 1e-9) | (q > lim[:, 1] + 1e-9), axis=1)
    if np.any(outside):
        i = int(np.flatnonzero(outside)[0])
        raise RobocalError(f"compensate: the corrected command of pose {i + 1} leaves the joint limits")
    return r, err


def reach(model: MeasurementModel, theta: np.ndarray, points: list[tuple[int, np.ndarray]], target_mm: np.ndarray,
          r0: np.ndarray, M: np.ndarray, off: np.ndarray, ctx: PoseContext | None = None, iterations: int = 10,
          tol_mm: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Readings (N, m) that put the model's ``points`` ((frame, position in it) each) at ``target_mm`` (N, K, 3),
    Gauss-Newton from ``r0`` on the readings (joint = M reading + off): the one inverse of the forward model
    (compensation, the ISO 9283 cube's commands).  Returns the readings and the remaining error (N,) in mm, the
    largest over the points."""
    r = np.array(np.atleast_2d(r0), float)
    target = np.asarray(target_mm, float).reshape(len(r), -1)
    err = np.full(len(r), np.inf)
    for _ in range(iterations):
        q = r @ M.T + off
        evs = [model.evaluate(q, ctx, theta, jacobian=True, tool_mm=xyz, link=f) for f, xyz in points]
        d = target - np.concatenate([ev.point_mm for ev in evs], axis=1)                   # (N, 3K)
        err = np.max(np.linalg.norm(d.reshape(len(r), -1, 3), axis=-1), axis=1)
        if np.all(err < tol_mm):
            break
        Jr = np.concatenate([np.matmul(ev.joint_jacobian, M) for ev in evs], axis=1)    # (N, 3K, m)
        r = r + np.einsum("nij,nj->ni", np.linalg.pinv(Jr), d)
    return r, err


def points_to_compensate(im: IdentifiedModel) -> list[tuple[int, np.ndarray]]:
    """(frame, identified position in that frame) of every tool point: the reference alone for a robot with one."""
    robot = im.model.robot
    pts = identified_tool_points(im.model, im.theta)
    if len(pts) <= 1:
        i = im.model.kin.index["tool.x_mm"]
        return [(robot.point_frame(), np.asarray(im.theta[i:i + 3], float))]
    return [(robot.point_frame(k), v) for k, v in pts.items()]


def nominal_in_same_frame(im: IdentifiedModel) -> MeasurementModel:
    """The description's geometry placed with the identified base and tool (what an uncompensated controller
    believes, in the measurement frame)."""
    m = MeasurementModel(im.nominal_robot)
    for name in m.kin.names:
        if name.startswith(("base.", "tool.")):
            m.kin.nominal[m.kin.index[name]] = im.theta[im.model.index[name]]
    return m


__all__ = ["save_model", "load_model", "model_from_document", "model_document",
           "robot_from_theta", "corrected_readings", "predict",
           "compensate_command", "compensate_readings", "reach", "points_to_compensate", "nominal_in_same_frame", "IdentifiedModel", "unit_of", "DEG"]
