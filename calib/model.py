"""The one forward measurement model: kinematics + non-geometric effects + instruments, vectorised over poses.

``MeasurementModel(robot, effects)`` owns one parameter vector ``theta``: the geometric parameters of the chain
(:class:`calib.kinematics.Kinematics`, base and tool included) followed by each effect's parameters.  For joint readings
``q`` (N, n) and the pose conditions (:class:`calib.effects.PoseContext`) it predicts

* the true joint angles (readings + joint-stage effects),
* the tool point in the measurement frame and its Jacobian with respect to every entry of ``theta``,
* the theodolite readings of that point from any set of stations, with their Jacobian (so identification can use
  raw angles as observations).

Prediction, identification, the twin, the emulators, design of experiments and diagnosis all call this class; none of
them has its own copy of the math.

Approximation stated once: loads (gravity and external torques) are evaluated in the configuration given by the joint
readings.  Their dependence on the geometric parameters (compliance x the change of torque with a parameter) enters
the Jacobian only where it changes the result, by the rule of :func:`torque_term_matters` (bound on its relative
size above 1 %); the predicted points are exact either way.

Cost: :meth:`MeasurementModel.evaluate` without a Jacobian computes points only; the Jacobian is completed from the
same pass on demand (:meth:`MeasurementModel.complete_jacobian`), so a least-squares loop that asks for the residuals
and then for the Jacobian at the same parameters runs the chain once.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .effects import Effect, Loads, PoseContext
from .effects.base import ElementMotions
from .kinematics import ChainPass, Kinematics, kept_arrays
from .robot import Robot
from .theodolite import Station


@dataclass
class Evaluation:
    """The model evaluated at N poses."""

    point_mm: np.ndarray                  # (N, 3)
    theta_rad: np.ndarray                 # (N, n) true joint angles
    jacobian: np.ndarray | None           # (N, 3, P_total) d point / d theta
    joint_jacobian: np.ndarray | None     # (N, 3, n) d point / d joint angle
    loads: Loads | None
    chain: ChainPass
    #: what :meth:`MeasurementModel.complete_jacobian` needs to add the Jacobian later without a second pass
    state: "_State | None" = field(default=None, repr=False)


@dataclass
class _State:
    q: np.ndarray
    ctx: PoseContext
    vals: list
    grads: dict
    link: int | None
    load_pass: ChainPass | None       # the chain at the joint readings, where the loads were evaluated


@dataclass
class _ElementTerms:
    """See :meth:`MeasurementModel._element_terms`."""

    a: np.ndarray              # (N, E, 3) element axes
    rot: np.ndarray            # (E,) rotation elements
    level: np.ndarray          # (E,) the frame an element belongs to: base 0, link k, tool n + 1
    v: np.ndarray              # (N, E, 3) change of the moment of what the element moves
    proximal: np.ndarray       # (k, E) the element moves joint j's axis with all it carries
    dist_w: np.ndarray         # (Nc, k, E) 1 where the element moves part of what joint j carries
    Sj: np.ndarray             # (N, k, 3) sum of the forces joint j carries
    Pj: np.ndarray             # (N, k, 3, 3) sum of p_b F_b^T over them


class MeasurementModel:
    def __init__(self, robot: Robot, effects: list[Effect] | tuple = (), stations: list[str] | None = None):
        """``stations``: the names of the instrument set-ups the station indices of :class:`calib.targets.
        TargetContext` stand for (0: the reference, ``station_offset`` effect k: the k-th), so rows are matched to
        their set-up by name; ``[]`` for a model identified without a ``station`` column, None when unknown (a
        model file written before the names were kept)."""
        self.robot = robot
        self.stations = None if stations is None else [str(s) for s in stations]
        self.kin = Kinematics(robot)
        self.effects: list[Effect] = list(effects)
        self.names: list[str] = list(self.kin.names)
        self.effect_slices: list[slice] = []
        seen: dict[str, int] = {}
        for e in self.effects:
            start = len(self.names)
            # a second effect of the same kind on the same joint (candidate orders in the diagnosis) gets "@2", ...
            k = seen[e.label] = seen.get(e.label, 0) + 1
            label = e.label if k == 1 else f"{e.label}@{k}"
            self.names += [f"{label}.{p}" for p in e.param_names]
            self.effect_slices.append(slice(start, len(self.names)))
        self.index = {n: i for i, n in enumerate(self.names)}
        self.n_geometric = self.kin.P
        self.length_idx = np.array([i for i, n in enumerate(self.kin.names)
                                    if n.startswith("j") and (n.endswith(".a_mm") or n.endswith(".d_mm"))])
        m = robot.mass_kg
        self._has_mass = bool(np.any(m > 0))
        # which frames each joint's variable moves (a joint carries every force fixed in them) and which frames lie
        # between a frame and the base: the "beyond" of a chain, as a tree has it
        self._moved = robot.frames_moved()                                           # (n, n+1)
        self._ancestors = robot.frame_ancestors()                                    # (n+1, n+1)
        self._spread = None if np.array_equal(robot.variable_of, np.arange(robot.n)) else robot.variable_spread()
        # the frame of each tool point (rows of a target context measure the point they name; on a tree the
        # points may sit on different branches)
        self._pivot_mm = self._moment_pivots()
        frames = [robot.point_frame(k) for k in robot.tool_points_mm]
        self._target_frames = np.array(frames, int) if len(set(frames)) > 1 else None
        self._structures: dict[tuple, tuple] = {}      # which joint carries which body (see _structure)
        # the frames of the bodies every pose has (the links' weights, then the tool's: code n + 1), read-only
        self._own_bodies = np.arange(1, robot.n + 2)
        self._own_bodies.flags.writeable = False

    @property
    def P(self) -> int:
        return len(self.names)

    def _moment_pivots(self) -> np.ndarray | None:
        """(n,) mm along each joint's axis: where the moment-driven effects take the moment a joint carries (None:
        every joint at its frame's origin).  Two effects on one joint must agree: the loads have one moment."""
        pivot = np.zeros(self.robot.n)
        seen: dict[int, float] = {}
        for e in self.effects:
            if e.moment_driven:
                for j, s in zip(e.moment_joints(), e.moment_pivots_mm()):
                    if seen.setdefault(j, s) != s:
                        raise ValueError(f"joint {j + 1}: two moment-driven effects bend it about different pivots "
                                         f"({seen[j]:g} and {s:g} mm along its axis)")
                    pivot[j] = s
        return pivot if np.any(pivot != 0) else None

    @property
    def nominal(self) -> np.ndarray:
        """The parameter vector from the robot description and the effects' current values."""
        return np.concatenate([self.kin.nominal] + [e.values for e in self.effects])

    def context(self, n_poses: int, **kw) -> PoseContext:
        return PoseContext(n_poses, self.robot.n, **kw)

    # -- loads ---------------------------------------------------------------------------------------------------
    def gravity_n_per_kg(self, theta: np.ndarray | None = None) -> np.ndarray:
        """(3,) the weight of one kilogram in the measurement frame (the description's gravity carried by the base):
        a hung mass m pulls ``m * gravity_n_per_kg()`` at its point."""
        geo = (self.nominal if theta is None else np.asarray(theta, float))[: self.n_geometric]
        fp = self.kin.forward(np.zeros((1, self.robot.n)), geo)
        return fp.gravity()[0].copy()

    def _bodies(self, fp: ChainPass, ctx: PoseContext, values: list | None = None):
        """Every force acting on the chain, with the frame it is fixed in: the links' weights at their centres of
        mass (frame j), the payload and tool force at the tool point (beyond frame n: n + 1), the point forces of
        ``ctx`` (frame ``point_force_link``), then the bodies of the load-stage effects (identified mass moments,
        :meth:`calib.effects.Effect.bodies`, at ``values``: each effect's parameters, default its own).  Returns
        positions (N, B, 3) m, forces (N, B, 3) N, frames (B,)."""
        r = self.robot
        n = r.n
        g_world = fp.gravity()                                                        # (N, 3)
        com = self.kin.point_on(fp, self._own_bodies[:n], r.com_mm)                   # (N, n, 3)
        F_tool = ctx.payload_kg[:, None] * g_world + ctx.tool_force_n                 # (N, 3)
        pos = [com, fp.point[:, None, :]]
        F = [r.mass_kg[None, :, None] * g_world[:, None, :], F_tool[:, None, :]]
        link = [self._own_bodies]
        if len(ctx.point_force_link):
            pos.append(self.kin.point_on(fp, ctx.point_force_link, ctx.point_force_mm))
            F.append(ctx.point_force_n)
            link.append(ctx.point_force_link)
        for p_mm, mass, _, frames in self._effect_bodies(fp, values):
            pos.append(p_mm)
            F.append(mass[None, :, None] * g_world[:, None, :])
            link.append(frames)
        link = self._own_bodies if len(link) == 1 else np.concatenate(link).astype(int)
        return np.concatenate(pos, axis=1) * 1e-3, np.concatenate(F, axis=1), link

    def _effect_bodies(self, fp: ChainPass, values: list | None) -> list:
        """(positions mm, masses kg, d masses / d values, frames) of every load-stage effect, in effect order."""
        vals = [e.values for e in self.effects] if values is None else values
        return [e.bodies(fp, v) for e, v in zip(self.effects, vals) if e.adds_bodies]

    def _body_derivative(self, fp: ChainPass, ctx: PoseContext, values: list) -> dict:
        """d(torque) (N, n, K) and d(moment about the joint origin) (N, n, 3, K) per load-stage effect (keyed by its
        index) with respect to its own parameters: its bodies' weights enter linearly, where they hang."""
        g = fp.gravity()                                                              # (N, 3)
        z, o = fp.joint_axis, self._pivots(fp) * 1e-3
        out = {}
        for i, (e, v) in enumerate(zip(self.effects, values)):
            if not e.adds_bodies:
                continue
            p_mm, _, dmass, frames = e.bodies(fp, v)
            carried = self._carried(fp, np.asarray(frames, int))                      # (Nc, n, K)
            unit = _cross(p_mm[:, None] * 1e-3 - o[:, :, None], g[:, None, None, :])  # (N, n, K, 3) per kg
            dM = np.einsum("njkc,njk,kp->njcp", unit, np.broadcast_to(carried, unit.shape[:3]), dmass)
            out[i] = (np.einsum("njcp,njc->njp", dM, z), dM)
        return out

    def _body_frames(self, fp: ChainPass, link: np.ndarray) -> np.ndarray:
        """(Nc, B) the frame (0..n) each body is fixed in: ``link`` with the tool body (code n + 1) on the tool
        point's frame, which on a tree may differ per pose (Nc = N) -- else Nc = 1."""
        n = self.robot.n
        frames = np.where(link > n, 0, link)[None, :]
        tool = np.asarray(fp.point_frame if fp.point_link is None else fp.point_link)
        if tool.ndim:
            frames = np.broadcast_to(frames, (len(tool), len(link))).copy()
            frames[:, link > n] = tool[:, None]
        else:
            frames[:, link > n] = int(tool)
        return frames

    def _carried(self, fp: ChainPass, link: np.ndarray) -> np.ndarray:
        """(Nc, n, B) 1.0 where joint j carries body b: the body is fixed in a frame the joint's variable moves."""
        kept = self._structure(fp, link)
        if kept is not None:
            return kept[1]
        frames = self._body_frames(fp, link)
        return self._moved[:, frames].transpose(1, 0, 2).astype(float)

    def _beyond(self, fp: ChainPass, link: np.ndarray) -> np.ndarray:
        """(Nc, n, B) 1.0 where body b lies beyond link j's end: in the subtree of frame j+1, and not on that frame
        itself unless it is the tool body (a chain: frame > j + 1, the tool always)."""
        kept = self._structure(fp, link)
        if kept is not None:
            return kept[2]
        return self._beyond_of(self._body_frames(fp, link), link)

    def _beyond_of(self, frames: np.ndarray, link: np.ndarray) -> np.ndarray:
        """:meth:`_beyond` from the bodies' frames (:meth:`_body_frames`)."""
        n = self.robot.n
        below = self._ancestors[frames][:, :, 1:]                                     # (Nc, B, n)
        own = frames[:, :, None] == np.arange(1, n + 1)[None, None, :]
        return (below & (~own | (link > n)[None, :, None])).transpose(0, 2, 1).astype(float)

    def _structure(self, fp: ChainPass, link: np.ndarray) -> tuple | None:
        """(frames, carried, beyond) of bodies fixed in frames ``link`` with the tool point in one frame for every
        pose: which joint carries which body depends on the chain and the frames alone, not on the pose, so a model
        evaluated one pose at a time (a session's twin) works it out once.  The same arrays as made afresh (the
        same expressions), kept read-only.  None when the tool point's frame varies per pose (a tree's rows)."""
        tool = fp.point_frame if fp.point_link is None else fp.point_link
        if isinstance(tool, np.ndarray) and tool.ndim:
            return None

        def make() -> tuple:
            frames = self._body_frames(fp, link)
            return frames, self._moved[:, frames].transpose(1, 0, 2).astype(float), self._beyond_of(frames, link)

        return kept_arrays(self._structures, (link.tobytes(), int(tool)), make, 64)

    def loads(self, fp: ChainPass, ctx: PoseContext, derivative: bool = False, values: list | None = None) -> Loads:
        """Torque about every joint axis (N m) and the force carried at the end of every link (N), per pose.

        Joint j carries every force fixed in a frame its variable moves (frame j or beyond on a chain; on a tree,
        every branch below it: ``sum (p_i - o_j) x F_i . z_j``); the end of link j carries those fixed beyond its
        end frame.  With ``derivative``, also d(torque)/d(geometric parameter) (N, n, P_geometric): each elementary
        motion of the chain moves rigidly what lies beyond it (the points where the forces act and the joint axes),
        while gravity and the external forces keep their direction.  ``values``: the effects' parameters (the
        identified bodies of load-stage effects), default their own.
        """
        n = self.robot.n
        parts = self._torque_parts(fp, ctx, values)
        pos, F, link, _, z, o, M, _ = parts
        tau = np.einsum("njc,njc->nj", M, z) + ctx.joint_torque_nm
        tip = np.matmul(self._beyond(fp, link), F)                                    # force beyond link j's end
        # 1 kg hung at the tool point (body n), about every joint that carries it: an unknown end-effector mass
        per_kg = np.einsum("njc,njc->nj", _cross(pos[:, n:n + 1] - o, fp.gravity()[:, None, :]), z) * parts[3][..., n]
        ctx_pts = slice(n + 1, n + 1 + len(ctx.point_force_link))                     # the context's point forces
        loads = Loads(joint_torque_nm=tau, tip_force_n=tip, point_force_n=F[:, ctx_pts],
                      point_at_mm=pos[:, ctx_pts] * 1e3, point_link=link[ctx_pts], joint_moment_nm=M,
                      frames_moved=self._moved, tool_torque_per_kg=per_kg)
        if derivative:
            loads.dtau_dgeo = self._torque_derivative(fp, *parts)
        return loads

    def _pivots(self, fp: ChainPass) -> np.ndarray:
        """(N, n, 3) mm: the point on each joint's axis the carried moment is taken about -- the origin of the frame
        its link starts from, moved along the axis by the pivot of a moment-driven effect on it (where the joint
        bends: :meth:`calib.effects.Effect.moment_pivots_mm`).  The torques about the axes do not depend on it."""
        if self._pivot_mm is None:
            return fp.joint_origin
        return fp.joint_origin + self._pivot_mm[None, :, None] * fp.joint_axis

    def _torque_parts(self, fp: ChainPass, ctx: PoseContext, values: list | None = None):
        """The bodies and the moment about every joint of what it carries (see :meth:`loads`)."""
        pos, F, link = self._bodies(fp, ctx, values)
        carried = self._carried(fp, link)                                             # (Nc, n, B)
        z, o = fp.joint_axis, self._pivots(fp) * 1e-3                                 # (N, n, 3)
        mom = _cross(pos, F)                                                          # (N, B, 3)
        tail_mom = np.matmul(carried, mom)
        tail_F = np.matmul(carried, F)
        M = tail_mom - _cross(o, tail_F)                                              # (N, n, 3)
        return pos, F, link, carried, z, o, M, tail_F

    def _torque_derivative(self, fp, pos, F, link, carried, z, o, M, tail_F, joints=None):
        """d(torque)/d(geometric element) (N, n, E); see :meth:`loads`.  ``joints`` (0-based): only those rows
        (the rest zero) -- the Jacobian needs the joints whose deflection follows the torque, not all.

        Joint j carries the bodies b of link j or beyond, tau_j = z_j . sum (p_b - o_j) x F_b.  With the tail sums
        S_m = sum F_b and P_m = sum p_b F_b^T over the bodies of link m or beyond, an element e (axis a, through o_e;
        it moves the bodies of its own link L_e and beyond) changes tau_j by

        * L_e < j (e moves joint j's axis, origin and bodies together): a rotation is, with the forces fixed in
          direction, the forces turned the other way: ``a . (Q_j z_j - tr(Q_j) z_j)`` with
          ``Q_j = P_j - o_j S_j^T``; a translation changes nothing;
        * L_e >= j (the axis stays, the bodies beyond e move): ``z_j . v_e`` with, for a rotation,
          ``v_e = Q'_e a - tr(Q'_e) a``, ``Q'_e = P_{L_e} - o_e S_{L_e}^T`` (from sum (a x (p_b - o_e)) x F_b), and
          for a translation ``v_e = 1e-3 a x S_{L_e}``.

        Both are a vector per joint or per element dotted with another, so the cost is that of the Jacobian's own
        columns, not elements x joints x bodies (this runs in every Jacobian of a torque-driven model that keeps
        the term)."""
        n = self.robot.n
        js = np.arange(n) if joints is None else np.asarray(joints, int)
        t = self._element_terms(fp, pos, F, link, carried, js)
        zj, oj = z[:, js], o[:, js]
        # joints: w_j = Q_j z_j - tr(Q_j) z_j, Q_j = P_j - o_j S_j^T over the bodies joint j carries
        Qz = np.einsum("nkcd,nkd->nkc", t.Pj, zj) - oj * np.einsum("nkd,nkd->nk", t.Sj, zj)[..., None]
        trQ = np.einsum("nkcc->nk", t.Pj) - np.einsum("nkc,nkc->nk", oj, t.Sj)
        w = Qz - trQ[..., None] * zj                                                  # (N, k, 3)
        d_prox = np.matmul(w, t.a.transpose(0, 2, 1)) * t.rot[None, None, :]          # (N, k, E)
        d_dist = np.matmul(zj, t.v.transpose(0, 2, 1))
        dtau = np.zeros((len(pos), n, len(t.level)))
        dtau[:, js] = np.where(t.proximal[None], d_prox, d_dist * t.dist_w)
        dtau[:, :, t.level == 0] = 0.0      # gravity is given in frame 0: the base carries it along
        return dtau

    def _moment_derivative(self, fp, pos, F, link, carried, z, o, M, tail_F, joints) -> np.ndarray:
        """d(moment about joint j's origin of all it carries) / d(geometric element) (N, k, 3, E) for ``joints``
        (0-based): the vector form of :meth:`_torque_derivative`, for effects driven by the whole moment (lateral
        compliance).  An element that moves joint j's origin with all it carries (proximal) turns the moment with it
        and, the forces keeping their direction, adds ``Q_j^T a - tr(Q_j) a`` (a rotation; a translation changes
        nothing); one that moves part of what j carries adds ``v_e``; the base turns gravity too: ``a x M_j``."""
        js = np.asarray(joints, int)
        t = self._element_terms(fp, pos, F, link, carried, js)
        Mj, oj = M[:, js], o[:, js]
        QTa = np.einsum("nkcd,nec->nked", t.Pj, t.a) - np.einsum("nkd,nec,nkc->nked", t.Sj, t.a, oj)
        trQ = np.einsum("nkcc->nk", t.Pj) - np.einsum("nkc,nkc->nk", oj, t.Sj)
        turn = _cross(t.a[:, None], Mj[:, :, None])                                   # (N, k, E, 3): a x M_j
        prox = turn + QTa - trQ[:, :, None, None] * t.a[:, None]
        prox = np.where(t.level[None, None, :, None] == 0, turn, prox) * t.rot[None, None, :, None]
        dist = t.v[:, None] * t.dist_w[..., None]
        return np.where(t.proximal[None, :, :, None], prox, dist).transpose(0, 1, 3, 2)

    def _element_terms(self, fp, pos, F, link, carried, js) -> "_ElementTerms":
        """What the torque and moment derivatives share: per element, the change ``v_e`` of the moment of what it
        moves (from the tail sums of its own link), which joints it moves proximally or distally, and the tail sums
        ``S_j``, ``P_j`` of what each joint in ``js`` carries."""
        kin = self.kin
        n = self.robot.n
        N = len(pos)
        level = np.minimum(kin.link_of, n + 1)                                        # base 0, link k, tool n + 1
        rot = kin.kinds >= 3
        a, oe = fp.elem_axis, fp.elem_origin * 1e-3                                   # (N, E, 3)
        # tail m: the bodies an element of frame m moves (the subtree of frame m; m = n + 1: the tool body alone)
        frames = self._body_frames(fp, link)                                          # (Nc, B)
        tail = np.concatenate([self._ancestors[frames].transpose(0, 2, 1),           # (Nc, n+1, B)
                               np.broadcast_to((link > n)[None, None, :], (len(frames), 1, len(link)))],
                              axis=1).astype(float)
        pF = (pos[:, :, :, None] * F[:, :, None, :]).reshape(N, -1, 9)
        S = np.matmul(tail, F)                                                        # (N, M, 3)
        P = np.matmul(tail, pF).reshape(N, -1, 3, 3)
        cj = carried[..., js, :] if carried.ndim == 3 else carried[None, js]
        Sj, Pj = np.matmul(cj, F), np.matmul(cj, pF).reshape(N, len(js), 3, 3)
        # elements: v_e from the tail of the element's own link
        v = np.empty_like(a)                                                          # (N, E, 3)
        trP = np.einsum("nmcc->nm", P)
        for m in np.unique(level):                                                    # the elements of each tail
            e = np.flatnonzero(level == m)
            r, t = e[rot[e]], e[~rot[e]]
            Sm = S[:, m, :, None]                                                     # (N, 3, 1)
            ar, orr = a[:, r], oe[:, r]
            Qa = np.matmul(ar, P[:, m].transpose(0, 2, 1)) - orr * np.matmul(ar, Sm)  # (P_m - o_e S_m^T) a
            trQ = trP[:, m, None] - np.matmul(orr, Sm)[..., 0]
            v[:, r] = Qa - trQ[..., None] * ar
            v[:, t] = 1e-3 * _cross(a[:, t], S[:, m, None, :])
        # an element between the base and joint j's axis moves the axis with what it carries (proximal); one in
        # a frame j's variable moves moves part of what j carries (distal); on a tree, one on another branch
        # moves nothing j carries.  A chain: every element is one or the other (L_e <= j or beyond).
        pf = kin.parent_frame[js]
        lev = np.minimum(level, n)
        proximal = self._ancestors[pf][:, lev] & (level <= n)[None, :]              # (k, E)
        distal = self._moved[js][:, lev] & (level <= n)[None, :]
        tool_carried = cj[..., link > n].sum(axis=-1)                                 # (Nc, k): j carries the tool
        dist_w = np.where(level <= n, distal[None].astype(float), tool_carried[..., None])
        return _ElementTerms(a, rot, level, v, proximal, dist_w, Sj, Pj)

    # -- evaluation ----------------------------------------------------------------------------------------------
    def evaluate(self, q_rad, ctx: PoseContext | None = None, theta: np.ndarray | None = None,
                 jacobian: bool = False, tool_mm=None, link: int | None = None,
                 torque_derivative: bool | None = None) -> Evaluation:
        """Predict tool points for joint readings ``q_rad`` (N, n); optionally the Jacobian w.r.t. ``theta``.

        ``tool_mm`` overrides the tool point: (3,) for all poses or (N, 3) per pose (targets A1/A2, ruler points).
        With ``link=j`` (0..n), ``tool_mm`` is a point fixed in frame j instead: it moves with link j, the joints
        beyond j do not move it, and the tool columns of the Jacobian are its derivative w.r.t. its own coordinates.
        Without ``jacobian`` only the points are computed; :meth:`complete_jacobian` adds the Jacobian to such an
        evaluation later without a second forward pass (identification asks for residuals, then for the Jacobian
        at the same parameters).  ``torque_derivative``: see :meth:`complete_jacobian`.
        """
        # copies, not views: the evaluation keeps them for complete_jacobian, which may run after the caller has
        # reused its arrays (an optimiser stepping theta in place)
        q = np.atleast_2d(np.array(q_rad, dtype=float))
        N, n = q.shape
        ctx = ctx or self.context(N)
        theta = self.nominal if theta is None else np.array(theta, dtype=float)
        geo = theta[: self.n_geometric]
        if link is not None:
            link = self.kin.check_link(link)
            if tool_mm is None:
                raise ValueError("evaluate(link=...) needs tool_mm, the point in that frame")
        elif tool_mm is not None:
            geo = self.kin.params_with_tool(tool_mm, geo)
        vals = [theta[s] for s in self.effect_slices]
        dgeo, grads = self._stage("geometry", vals, lambda e, v: e.geometry_delta(geo, self.length_idx, ctx, v))
        geo_pose = geo if not isinstance(dgeo, np.ndarray) else np.broadcast_to(geo, (N, self.n_geometric)) + dgeo
        frame = self.row_frames(ctx) if link is None else None
        load_pass, loads = None, None
        if any(e.needs_loads for e in self.effects):
            load_pass = self.kin.forward(q, geo_pose, frame)
            loads = self.loads(load_pass, ctx, values=vals)
        dq, g = self._stage("joint", vals, lambda e, v: e.joint_delta(q, ctx, loads, v))
        if self._spread is not None and isinstance(dq, np.ndarray):
            dq = dq @ self._spread.T              # a joint's change turns every link that shares its variable
        th = q + dq
        grads.update(g)
        if load_pass is not None and not isinstance(dq, np.ndarray) and link is None:
            fp = load_pass              # no joint-stage effect: the loads' pass is the chain at the true angles
        else:
            fp = self.kin.forward(th, geo_pose, frame)
        if link is not None:
            fp.point_link = link
            fp.point = self.kin.point_on(fp, [link], np.reshape(tool_mm, (-1, 1, 3)))[:, 0]
        dp, g = self._stage("point", vals, lambda e, v: e.point_delta(fp, fp.point, loads, v))
        point = fp.point + dp
        grads.update(g)
        ev = Evaluation(point, th, None, None, loads, fp, _State(q, ctx, vals, grads, link, load_pass))
        if jacobian:
            self.complete_jacobian(ev, torque_derivative)
        return ev

    def row_frames(self, ctx: PoseContext) -> np.ndarray | None:
        """(N,) the frame of the point each row measures (its target's), or None when every point shares one."""
        target = getattr(ctx, "target", None)
        if self._target_frames is None or target is None:
            return None
        return self._target_frames[np.asarray(target, int)]

    def complete_jacobian(self, ev: Evaluation, torque_derivative: bool | None = None) -> Evaluation:
        """Fill ``ev.jacobian`` (N, 3, P) and ``ev.joint_jacobian`` (N, 3, n) from the evaluation's own pass.

        ``torque_derivative``: whether the geometric columns carry the change of the joint deflections with the
        torques that a geometric parameter moves (torque-driven effects only).  None (default) applies the rule of
        :func:`torque_term_matters`; True or False force it."""
        if ev.jacobian is None:
            st = ev.state
            if st is None:
                raise ValueError("this evaluation keeps no state to add a Jacobian to")
            ev.jacobian, ev.joint_jacobian = self._jacobian(ev, torque_derivative)
        return ev

    def torque_gain(self, ev: Evaluation) -> np.ndarray | None:
        """(N, n) d deflection / d torque of every joint at an evaluation (None: no torque-driven effect)."""
        st = ev.state
        if ev.loads is None or st is None or not any(e.torque_driven for e in self.effects):
            return None
        return sum(e.torque_gain(st.q, st.ctx, ev.loads, v) for e, v in zip(self.effects, st.vals) if e.torque_driven)

    def _stage(self, stage: str, vals, call) -> tuple:
        """The effects of one stage: the sum of their changes (0.0 when there are none) and each one's derivative
        w.r.t. its own parameters, keyed by the effect's index."""
        delta, grads = 0.0, {}
        for i, (e, v) in enumerate(zip(self.effects, vals)):
            if e.stage == stage:
                d, grads[i] = call(e, v)
                delta = delta + d
        return delta, grads

    def _jacobian(self, ev: Evaluation, torque_derivative: bool | None):
        """d point / d theta (N, 3, P) and d point / d joint angle (N, 3, n), from the chain's screws and each
        effect's own derivative carried through what its stage moves (the joints, the geometry or the point)."""
        st, fp, loads = ev.state, ev.chain, ev.loads
        q, ctx, vals, grads = st.q, st.ctx, st.vals, st.grads
        ng = self.n_geometric
        Je = self.kin.element_jacobian(fp, link=st.link)        # (N, 3, Pg)
        J = np.zeros((len(q), 3, self.P))
        J[:, :, :ng] = Je
        Jq = Je[:, :, self.kin.joint_elements]
        # a joint-stage change of joint k turns every link sharing k's variable (the branches of a tree)
        Jvar = Jq if self._spread is None else np.matmul(Jq, self._spread)
        gain = self.torque_gain(ev)
        moment = [i for i, e in enumerate(self.effects) if e.moment_driven] if loads is not None else []
        if torque_derivative is None and (gain is not None or moment):
            torque_derivative = self._keeps_torque_term(gain, loads, vals)
        parts = self._torque_parts(st.load_pass, ctx, vals) if torque_derivative and (gain is not None or moment) \
            else None
        if gain is not None and torque_derivative:
            # joint deflections follow the torques, and the torques move with the geometry
            joints = np.flatnonzero(np.any(gain != 0, axis=0))
            dtau = self._torque_derivative(st.load_pass, *parts, joints=joints)
            J[:, :, :ng] += np.matmul(Jvar[:, :, joints], gain[:, joints, None] * dtau[:, joints])
        gains = {i: self.effects[i].moment_gain(fp, fp.point, loads, vals[i]) for i in moment}
        if moment and torque_derivative:
            self._moment_geometry(J, ev, Je, gains, parts)
        # a geometry-stage effect changes the geometry: its columns follow the geometric ones, load terms included
        through = {"joint": Jvar, "geometry": J[:, :, :ng].copy() if torque_derivative else Je}
        for i, (e, s, v) in enumerate(zip(self.effects, self.effect_slices, vals)):
            if e.stage == "geometry":
                # the effect's change of the geometry depends on the geometry: its own chain rule
                J[:, :, :ng] = e.geometry_chain(J[:, :, :ng], self.length_idx, ctx, v)
            if e.stage == "load":
                continue
            if e.stage == "joint" and e.own_joint_only:
                k = e.joint - 1         # the same numbers as the product over every joint, whose other terms are 0
                J[:, :, s] = through["joint"][:, :, k, None] * grads[i][:, k, None, :]
                continue
            J[:, :, s] = grads[i] if e.stage == "point" else np.matmul(through[e.stage], grads[i])
        if st.load_pass is not None and any(e.adds_bodies for e in self.effects):
            self._body_columns(J, ev, Jvar, gain, gains)
        return J, Jq

    def _keeps_torque_term(self, gain, loads: Loads, vals) -> bool:
        """Whether the geometric columns carry the change of the loads (the rule of :func:`torque_term_matters`,
        over the joint deflections and the moment-driven displacements alike)."""
        size = torque_term_size(gain, loads) if gain is not None else 0.0
        for e, v in zip(self.effects, vals):
            if e.moment_driven:
                size = max(size, e.moment_term_size(loads, v))
        return size > TORQUE_TERM_THRESHOLD

    def _motions(self, fp: ChainPass, Je: np.ndarray) -> ElementMotions:
        """The elementary motions of ``fp`` for :meth:`calib.effects.Effect.geometry_jacobian`."""
        n = self.robot.n
        level = self.kin.link_of
        moves = np.zeros((n + 1, len(level)), bool)
        inside = level <= n
        moves[:, inside] = self._ancestors[:, level[inside]]
        return ElementMotions(fp.elem_axis, fp.elem_origin, self.kin.kinds >= 3, moves, Je)

    def _moment_geometry(self, J: np.ndarray, ev: Evaluation, Je: np.ndarray, gains: dict, parts) -> None:
        """Add to the geometric columns the change of every moment-driven displacement: its own frames and lever
        arms (the effect's :meth:`~calib.effects.Effect.geometry_jacobian`) and the moments it follows."""
        st, fp, loads = ev.state, ev.chain, ev.loads
        ng = self.n_geometric
        joints = sorted({j for i in gains for j in self.effects[i].moment_joints()})
        dM = self._moment_derivative(st.load_pass, *parts, joints=joints)             # (N, k, 3, E)
        motions = self._motions(fp, Je)
        for i, G in gains.items():
            e = self.effects[i]
            k = [joints.index(j) for j in e.moment_joints()]
            J[:, :, :ng] += np.einsum("nckd,nkde->nce", G, dM[:, k])
            J[:, :, :ng] += e.geometry_jacobian(fp, fp.point, loads, st.vals[i], motions)

    def _body_columns(self, J: np.ndarray, ev: Evaluation, Jvar: np.ndarray, gain, gains: dict) -> None:
        """The columns of the load-stage effects (identified mass moments): their weight changes the torques the
        joint deflections follow and the moments the moment-driven displacements follow."""
        st = ev.state
        for i, (dtau, dM) in self._body_derivative(st.load_pass, st.ctx, st.vals).items():
            s = self.effect_slices[i]
            if gain is not None:
                J[:, :, s] += np.matmul(Jvar, gain[:, :, None] * dtau)
            for m, G in gains.items():
                J[:, :, s] += np.einsum("nckd,nkdp->ncp", G, dM[:, self.effects[m].moment_joints()])

    def points(self, q_rad, ctx: PoseContext | None = None, theta=None, tool_mm=None, link=None) -> np.ndarray:
        return self.evaluate(q_rad, ctx, theta, False, tool_mm, link).point_mm

    # -- instruments ---------------------------------------------------------------------------------------------
    def readings(self, q_rad, stations: list[Station], ctx: PoseContext | None = None, theta=None,
                 faces=None, jacobian: bool = False, tool_mm=None):
        """Predicted theodolite readings (N, 2k) ordered (Hz_1, V_1, Hz_2, V_2, ...) and optionally d/d theta."""
        return self.readings_of(self.evaluate(q_rad, ctx, theta, jacobian, tool_mm), stations, faces, jacobian)

    @staticmethod
    def readings_of(ev: Evaluation, stations: list[Station], faces=None, jacobian: bool = False):
        """The readings of an evaluation's tool points (and their Jacobian through ``ev.jacobian``)."""
        faces = faces or [1] * len(stations)
        cols, Js = [], []
        for s, f in zip(stations, faces):
            if jacobian:
                hz, v, Js_ = s.observe(ev.point_mm, f, with_jacobian=True)
                Js.append(np.matmul(Js_, ev.jacobian))
            else:
                hz, v = s.observe(ev.point_mm, f)
            cols += [hz, v]
        out = np.stack(cols, -1)
        if jacobian:
            return out, np.concatenate(Js, axis=1)
        return out


#: the torque term's largest relative size in the Jacobian below which it is left out (see torque_term_matters)
TORQUE_TERM_THRESHOLD = 0.01


def torque_term_matters(gain: np.ndarray, loads: Loads, threshold: float | None = None) -> bool:
    """Whether the Jacobian needs the change of the joint deflections with the torques a geometric parameter moves.

    The term adds to the column of a geometric parameter e ``J_q,j * c_j * d tau_j / d e`` for every joint j whose
    deflection follows its torque with compliance c_j (``gain``).  Moving the chain by a rotation changes tau_j by at
    most the moment M_j of everything joint j carries (``loads.joint_moment_nm``), so relative to the column the term
    is about ``eps = max c_j |M_j|``: the joint deflection that moment would cause, in radians (a translation gives
    the same bound through the lever arm; measured per column: 0.1-1.5 eps).  The residuals stay exact either way, so
    leaving the term out changes only the solver's steps and the covariance.  Measured (``python
    benchmarks/bench_scaling.py --torque-term``, 1000 twin poses, thesis effects, term off against on): the thesis's
    Puma, eps 0.003: parameters within 0.003 sigma, sigmas within 0.04 %, the same held-out RMS; joints 10x more
    compliant, eps 0.03: 0.04 sigma, 0.3 %; 30x, eps 0.08: 0.09 sigma, 1.2 %.  Hence the rule: the term is computed
    when eps exceeds ``threshold`` (default :data:`TORQUE_TERM_THRESHOLD`, 1 %) -- a stiff arm skips what was most of
    a torque-aware Jacobian's cost; a soft one keeps the exact Jacobian.
    """
    threshold = TORQUE_TERM_THRESHOLD if threshold is None else threshold
    return bool(torque_term_size(gain, loads) > threshold)


def torque_term_size(gain: np.ndarray, loads: Loads) -> float:
    """``max c_j |M_j|`` over poses and joints (radians): the torque term's largest relative size in the Jacobian
    (see :func:`torque_term_matters`); infinite when the loads carry no moments to bound it with."""
    if loads.joint_moment_nm is None:
        return float("inf")
    return float(np.max(np.abs(gain) * np.linalg.norm(loads.joint_moment_nm, axis=-1), initial=0.0))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over the last axis (broadcast), component by component into one array (np.cross and np.stack copy
    and transpose: several times slower on the small arrays of one-pose evaluations).

    Up to :data:`SMALL_CROSS` vectors the three components are computed together, from each operand written twice
    along its last axis (``(a1, a2, a0) * (b2, b0, b1) - (a2, a0, a1) * (b1, b2, b0)``): five numpy calls instead of
    twenty-odd, where the calls' overhead is the cost (a session's twin evaluates one pose at a time).  Every
    component is the same product and difference of the same floats either way (tests/test_model_small_paths.py)."""
    if max(a.size, b.size) <= 3 * SMALL_CROSS:
        a2, b2 = np.concatenate((a, a), -1), np.concatenate((b, b), -1)
        return a2[..., 1:4] * b2[..., 2:5] - a2[..., 2:5] * b2[..., 1:4]
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


#: the most vectors of either operand :func:`_cross` computes from them written twice (above: per component)
SMALL_CROSS = 256
