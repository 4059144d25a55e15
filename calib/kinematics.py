"""Forward kinematics and the identification Jacobian of a serial chain, vectorised over poses.

The chain is written once as a sequence of *elementary motions* (translations and rotations about the current frame's
x, y or z axis), the way the Robotics Toolbox writes an ETS:

    base:   Tx Ty Tz Rz(yaw) Ry(pitch) Rx(roll)                     robot frame 0 in the measurement frame
    link j: Rz(theta_j + theta_offset_j) Tz(d_j) Tx(a_j) Rx(alpha_j) Ry(beta_j)    DH with the Hayati beta
    tool:   Tx Ty Tz                                                 tool point in frame n

Each elementary motion has exactly one named parameter (``j2.a_mm``, ``base.yaw_rad``, ``tool.z_mm`` ...) and joint
motions add the joint reading.  Why this form: the derivative of the tool point with respect to *any* parameter is then
the screw of that motion — ``axis`` for a translation, ``axis x (p - origin)`` for a rotation — so one forward pass gives
the analytic Jacobian for every parameter (geometry, base, tool) and for the joint angles, with no second copy of the
math.

How it runs (issue 18: the cost of a plain vectorised DH product): the five motions of a link are multiplied out in
closed form, for every link and pose at once, and the links are chained by one 3x3 product each, pose-last (the poses
are the contiguous last axis, so a product is a few multiply-adds of rows).  The screws of the elementary motions
(axis and a point on it) follow from the frames and are derived only when a Jacobian asks for them; a caller that
wants points pays for points.  The arrays the rest of robocal reads keep poses first (:class:`ChainPass`).

Units: mm and radians.
"""
from __future__ import annotations

import numpy as np

from .angles import rot_zyx
from .robot import Robot

TX, TY, TZ, RX, RY, RZ = range(6)
_AXIS = {TX: 0, TY: 1, TZ: 2, RX: 0, RY: 1, RZ: 2}

#: per-link parameter names, in chain order, with their elementary motion
LINK_PARAMS = (("theta_offset_rad", RZ), ("d_mm", TZ), ("a_mm", TX), ("alpha_rad", RX), ("beta_rad", RY))
BASE_PARAMS = (("x_mm", TX), ("y_mm", TY), ("z_mm", TZ), ("yaw_rad", RZ), ("pitch_rad", RY), ("roll_rad", RX))
TOOL_PARAMS = (("x_mm", TX), ("y_mm", TY), ("z_mm", TZ))


class ChainPass:
    """Everything one forward pass computes, for N poses of an n-joint robot.  All in the measurement frame.

    The pass works pose-last (``_R`` (n+1, 3, 3, N), ``_t`` (n+1, 3, N)): every product of the chain is then a few
    multiply-adds of contiguous rows over the poses, the fastest numpy offers for 3x3 matrices.  The pose-first views
    the rest of robocal reads (:attr:`frame_R`, :attr:`elem_axis` ...) are made on first use and kept, and the
    elementary motions' screws (what a Jacobian needs) are derived from the frames only when asked: a caller that
    wants points pays for points.
    """

    def __init__(self, point: np.ndarray, R: np.ndarray, t: np.ndarray, local: dict | None = None,
                 gravity_m_s2: np.ndarray | None = None, point_link: int | None = None,
                 parent_frame: np.ndarray | None = None, point_frame=None):
        self.point = point                          # (N, 3) tool point
        self._R, self._t = R, t                     # (n+1, 3, 3, N), (n+1, 3, N): frames 0..n, pose-last
        self._local = local                         # what the element screws need (Kinematics.forward)
        self._cache: dict[str, np.ndarray] = {}
        self.point_link = point_link                # frame the evaluated point is fixed in (None: the tool point)
        self.gravity_m_s2 = gravity_m_s2            # (3,) the description's gravity, in frame 0
        n = R.shape[0] - 1
        # the frame each link starts from (a chain: the previous link's end) and the tool point's frame per pose
        self.parent_frame = np.arange(n) if parent_frame is None else parent_frame
        self.point_frame = n if point_frame is None else point_frame

    def pose(self, k: int) -> "ChainPass":
        """Pose ``k`` as a one-pose pass (views, no copies): for code that looks at a batch one pose at a time."""
        N = len(self.point)

        def cut(v):
            return v[..., k:k + 1] if isinstance(v, np.ndarray) and v.ndim >= 2 and v.shape[-1] == N else v

        local = None if self._local is None else {key: cut(v) for key, v in self._local.items()}
        pf = self.point_frame if np.isscalar(self.point_frame) else self.point_frame[k:k + 1]
        return ChainPass(self.point[k:k + 1], self._R[..., k:k + 1], self._t[..., k:k + 1], local,
                         self.gravity_m_s2, self.point_link, self.parent_frame, pf)

    def _pose_first(self, key: str, make) -> np.ndarray:
        if key not in self._cache:
            self._cache[key] = np.ascontiguousarray(make())
        return self._cache[key]

    @property
    def frame_R(self) -> np.ndarray:
        """(N, n+1, 3, 3) frames 0..n (frame 0 = robot base after the base transform)."""
        return self._pose_first("frame_R", lambda: self._R.transpose(3, 0, 1, 2))

    @property
    def frame_t(self) -> np.ndarray:
        """(N, n+1, 3) origins of frames 0..n."""
        return self._pose_first("frame_t", lambda: self._t.transpose(2, 0, 1))

    def screws(self) -> tuple[np.ndarray, np.ndarray]:
        """The axis and a point on the axis of every elementary motion, element-major and pose-last (E, 3, N)."""
        if "ax" not in self._cache:
            self._cache["ax"], self._cache["org"] = _element_screws(self)
        return self._cache["ax"], self._cache["org"]

    @property
    def elem_axis(self) -> np.ndarray:
        """(N, E, 3) world direction of each elementary motion's axis."""
        return self._pose_first("elem_axis", lambda: self.screws()[0].transpose(2, 0, 1))

    @property
    def elem_origin(self) -> np.ndarray:
        """(N, E, 3) a point on each elementary motion's axis (the frame origin before the motion)."""
        return self._pose_first("elem_origin", lambda: self.screws()[1].transpose(2, 0, 1))

    def gravity(self) -> np.ndarray:
        """(N, 3) gravity (m/s^2) in the measurement frame: the description's, given in frame 0, carried by the base.
        The one source of the gravity direction for loads and effects (a wall- or ceiling-mounted robot's
        description says where down is)."""
        got = self._cache.get("gravity")
        if got is None:             # kept, read-only: the loads ask for it more than once per pass
            if self.gravity_m_s2 is None:
                raise ValueError("a chain pass built without the description's gravity (Kinematics.forward sets it)")
            g = self.gravity_m_s2
            R0 = self._R[0]
            got = self._cache["gravity"] = (R0[:, 0] * g[0] + R0[:, 1] * g[1] + R0[:, 2] * g[2]).T
            got.flags.writeable = False
        return got

    @property
    def joint_axis(self) -> np.ndarray:
        """(N, n, 3) unit axis of each joint (z of the frame its link starts from: frame j-1 of a chain)."""
        return self.frame_R[:, self.parent_frame][..., 2]

    @property
    def joint_origin(self) -> np.ndarray:
        """(N, n, 3) origin of the frame link j starts from (frame j-1 of a chain), a point on joint j's axis."""
        return self.frame_t[:, self.parent_frame, :]

    def tool_frame(self) -> tuple[np.ndarray, np.ndarray]:
        """The frame the tool point is fixed in, pose-last: R (3, 3, N), t (3, N) (a row's own frame on a tree)."""
        return _frame_at(self._R, self._t, self.point_frame)

    def link_beam(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """(start, end) (N, 3) each: the body of link j as a beam for bending, clamped at joint j's axis.

        Frame j-1 to frame j is an offset d_j along joint j's axis then the link's length a_j across it; the beam is
        the part across the axis (from the foot of frame j's origin on the axis) -- the part along the axis is the
        joint's own offset -- unless the link has no length across (a_j ~ 0: then the whole offset is the body)."""
        f = self.parent_frame[j - 1]
        start, end = self.frame_t[:, f], self.frame_t[:, j]
        z = self.frame_R[:, f, :, 2]
        seg = end - start
        perp = seg - np.einsum("nc,nc->n", seg, z)[:, None] * z
        across = np.linalg.norm(perp, axis=-1) > 1.0
        return np.where(across[:, None], end - perp, start), end

    @property
    def flange_R(self) -> np.ndarray:
        return self.frame_R[:, -1]

    @property
    def flange_t(self) -> np.ndarray:
        return self.frame_t[:, -1]


class Kinematics:
    """The chain of a :class:`Robot` with its parameter vector.

    ``names`` lists the parameters, ``nominal`` their values from the robot description.  :meth:`forward` accepts a
    parameter vector ``(P,)`` or one per pose ``(N, P)`` (thermal growth, a different tool target per pose ...).
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        n = robot.n
        kinds, joint, names, nominal = [], [], [], []
        base_vals = [*robot.base_xyz_mm, robot.base_rpy_rad[2], robot.base_rpy_rad[1], robot.base_rpy_rad[0]]
        for (pname, kind), val in zip(BASE_PARAMS, base_vals):
            kinds.append(kind), joint.append(-1), names.append(f"base.{pname}"), nominal.append(val)
        self.link_first_element = []
        for j in range(n):
            self.link_first_element.append(len(kinds))
            vals = (robot.theta_offset_rad[j], robot.d_mm[j], robot.a_mm[j], robot.alpha_rad[j], robot.beta_rad[j])
            for (pname, kind), val in zip(LINK_PARAMS, vals):
                kinds.append(kind)
                moving = "d_mm" if robot.prismatic[j] else "theta_offset_rad"
                joint.append(j if pname == moving else -1)
                names.append(f"j{j + 1}.{pname}")
                nominal.append(val)
        tool = robot.tool_point()
        for (pname, kind), val in zip(TOOL_PARAMS, tool):
            kinds.append(kind), joint.append(-1), names.append(f"tool.{pname}"), nominal.append(val)
        self.kinds = np.array(kinds)
        self.joint = np.array(joint)
        self.names: list[str] = names
        self.nominal = np.array(nominal, float)
        self.index = {name: i for i, name in enumerate(names)}
        self.n = n
        self.joint_elements = np.flatnonzero(self.joint >= 0)     # in joint order (one element per joint)
        # the frame each elementary motion belongs to: base 0, link j -> j, tool n + 1.  A point fixed in frame b is
        # moved by exactly the elements with link_of <= b.
        self.link_of = np.zeros(self.P, int)
        for j, first in enumerate(self.link_first_element):
            self.link_of[first:first + len(LINK_PARAMS)] = j + 1
        self.link_of[self.index["tool.x_mm"]:] = n + 1
        # what the closed-form pass reads: each link's five parameters, the tool point, which joints turn or slide
        self._link_cols = np.array(self.link_first_element, int)[:, None] + np.arange(len(LINK_PARAMS))  # (n, 5)
        self._tool_cols = np.arange(self.index["tool.x_mm"], self.index["tool.z_mm"] + 1)
        self._prismatic = np.asarray(robot.prismatic, bool)
        self._revolute = (~self._prismatic).astype(float)
        self._prismatic = self._prismatic.astype(float)
        self._revolute_col, self._prismatic_col = self._revolute[:, None], self._prismatic[:, None]
        self._any_prismatic = bool(self._prismatic.any())
        self._gravity = np.asarray(robot.gravity_m_s2, float)
        self._rot = self.kinds >= RX
        self._trans = ~self._rot
        # a branched robot: the frame each link starts from, which frames lie between a frame and the base, and
        # the frame the (reference) tool point is fixed in
        self.parent_frame = np.asarray(robot.parent_frame, int)
        self.is_chain = not robot.is_tree
        self.ancestors = robot.frame_ancestors()                                   # (n+1, n+1)
        self.tool_frame = robot.point_frame()
        self._nontool = np.flatnonzero(self.link_of <= n)
        self._pf_list = self.parent_frame.tolist()
        self._serial = bool(np.array_equal(self.parent_frame, np.arange(n)))     # link j starts from frame j - 1
        self._fixed: dict[bytes, tuple] = {}     # parameter vector (tool point aside) -> forward's fixed terms

    @property
    def P(self) -> int:
        return len(self.names)

    def params_with_tool(self, tool_mm, params: np.ndarray | None = None) -> np.ndarray:
        """A copy of ``params`` (default nominal) with the tool point replaced; tool_mm (3,) or (N, 3)."""
        p = np.array(self.nominal if params is None else params, float)
        tool_mm = np.asarray(tool_mm, float)
        if tool_mm.ndim == 2 and p.ndim == 1:
            p = np.broadcast_to(p, (len(tool_mm), p.size)).copy()
        p[..., self.index["tool.x_mm"]:self.index["tool.z_mm"] + 1] = tool_mm
        return p

    # -- forward pass ---------------------------------------------------------------------------------------------
    def forward(self, q_rad: np.ndarray, params: np.ndarray | None = None, point_frame=None) -> ChainPass:
        """Run the chain for joint angles ``q_rad`` (N, n).

        ``point_frame``: the frame the tool point is fixed in, one for all poses or (N,) one per pose (rows that
        measure targets on different branches of a tree); default the reference tool point's frame.

        Each link's motions ``Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)`` are multiplied out in closed form (one
        rotation and one offset per link, for all links and poses at once), then the links are chained by one batched
        3x3 product each: the cost of a plain DH product.  The elementary motions' screws are derived from these
        frames only when a Jacobian asks (:attr:`ChainPass.elem_axis`)."""
        q = np.asarray(q_rad, float)
        if q.ndim != 2:
            q = np.atleast_2d(q)
        if q.shape[-1] != self.n:
            raise ValueError(f"expected {self.n} joint angles per pose, got {q.shape[-1]}")
        N, n = q.shape[0], self.n
        p = self.nominal if params is None else np.asarray(params, float)
        if p.ndim == 2 and len(p) == 1 and N > 1:
            p = p[0]
        # link parameters link-major and pose-last: (5, n, 1) for one parameter vector, (5, n, N) for one per pose
        if p.ndim == 2 and N < SMALL_BATCH and self._same_but_tool(p):
            # one chain, a tool point per pose (targets on the flange evaluated together): the kept terms of the
            # first row, the same floats as each row's own (elementwise operations on the same numbers)
            lk, a, ca, sa, cb, sb, base, R0, twist, row2 = self._fixed_terms(p[0])
        elif p.ndim == 2:
            lk = p[..., self._link_cols].T
            a, ca, sa, cb, sb = lk[2], np.cos(lk[3]), np.sin(lk[3]), np.cos(lk[4]), np.sin(lk[4])
            base = p[..., :len(BASE_PARAMS)].T                                         # (6, N)
            R0 = rot_zyx(base[3], base[4], base[5])
            R0 = R0.transpose(1, 2, 0)
            twist, row2 = _twist_terms(ca, sa, cb, sb)
        else:
            lk, a, ca, sa, cb, sb, base, R0, twist, row2 = self._fixed_terms(p)
        qT = q.T
        theta = lk[0] + qT * self._revolute_col
        d = lk[1] + qT * self._prismatic_col if self._any_prismatic else lk[1]
        cs = np.empty((2, n, N))                                                       # cos, sin of theta
        np.cos(theta, out=cs[0])
        np.sin(theta, out=cs[1])
        A = _link_rotations(cs, ca, sa, twist, row2)
        # link offset Rz(theta) (a, 0, d)
        off = np.empty((n, 3, N))
        np.multiply(a[:, None], cs.transpose(1, 0, 2), out=off[:, :2])
        off[:, 2] = d
        R = np.empty((n + 1, 3, 3, N))
        t = np.empty((n + 1, 3, N))
        R[0] = R0
        t[0] = base[:3] if base.ndim == 2 else base[:3, None]
        pf = self.parent_frame
        if N < SMALL_BATCH:
            _small_chain(R, t, A, off, self._pf_list, self._serial)
        else:
            for j in range(n):
                _chain_step(R[pf[j]], t[pf[j]], A[j], off[j], R[j + 1], t[j + 1])
        ct, st = cs
        tool = p[..., self._tool_cols].T
        tool = tool if tool.ndim == 2 else tool[:, None]                               # (3, N) or (3, 1)
        frame = self.tool_frame if point_frame is None else _point_frames(point_frame, N, n)
        Rn, tn = _frame_at(R, t, frame)
        # t_n + R_n[:, 0] x + R_n[:, 1] y + R_n[:, 2] z, summed in that order (a reduction over the first axis adds
        # row after row), in fewer numpy calls than term by term
        terms = np.empty((4, 3, N))
        terms[0] = tn
        np.multiply(Rn, tool[None], out=terms[1:].transpose(1, 0, 2))
        point = np.add.reduce(terms, axis=0).T.copy()
        local = {"ct": ct, "st": st, "d": d, "base": base, "tool": tool}
        return ChainPass(point, R, t, local, gravity_m_s2=self._gravity, parent_frame=pf, point_frame=frame)

    def _same_but_tool(self, p: np.ndarray) -> bool:
        """Whether the rows of a per-pose parameter array (N, P) differ in the tool point alone."""
        ts = self._tool_cols[0]
        return ts == p.shape[1] - 3 and bool((p[1:, :ts] == p[0, :ts]).all())

    def _fixed_terms(self, p: np.ndarray) -> tuple:
        """What :meth:`forward` derives from one parameter vector alone (the links' parameters pose-last, the cosines
        and sines of their twists, the base's rotation), kept for the last few vectors: a session evaluates one model
        at one pose at a time, where these were about a tenth of a pass.  The same operations on the same numbers as
        before, so the same floats; the arrays are copies, read-only, shared by the passes that read them."""
        def make() -> tuple:
            lk = p[self._link_cols].T[:, :, None]
            base = p[:len(BASE_PARAMS)].copy()         # not a view: the caller may step its vector in place
            ca, sa, cb, sb = np.cos(lk[3]), np.sin(lk[3]), np.cos(lk[4]), np.sin(lk[4])
            return (lk, lk[2], ca, sa, cb, sb, base, rot_zyx(base[3], base[4], base[5])[..., None],
                    *_twist_terms(ca, sa, cb, sb))

        key = p[:self._tool_cols[0]].tobytes() if self._tool_cols[0] == len(p) - 3 else p.tobytes()
        return kept_arrays(self._fixed, key, make, 8)

    def points(self, q_rad: np.ndarray, params: np.ndarray | None = None) -> np.ndarray:
        """Tool points (N, 3) in the measurement frame."""
        return self.forward(q_rad, params).point

    def check_link(self, link: int) -> int:
        """``link`` as a frame index 0..n (0 base, j = link j); a ValueError otherwise."""
        if int(link) != link or not 0 <= link <= self.n:
            raise ValueError(f"frame index must be 0..{self.n}, got {link!r}")
        return int(link)

    @staticmethod
    def point_on(fp: ChainPass, link, point_mm) -> np.ndarray:
        """Points fixed in frames ``link`` (K,) at ``point_mm`` ((K, 3) or (N, K, 3), frame coordinates), in the
        measurement frame (N, K, 3): ``t_j + R_j p``.  Why here: the one place a point on a link is placed."""
        link = np.asarray(link, int)
        R, t = fp.frame_R[:, link], fp.frame_t[:, link]                      # (N, K, 3, 3), (N, K, 3)
        p = np.asarray(point_mm, float)
        if p.shape != t.shape and p.shape != t.shape[1:]:   # matmul broadcasts (K, 3) over the poses itself
            p = np.broadcast_to(p, t.shape)
        return t + np.matmul(R, p[..., None])[..., 0]

    # -- Jacobians ------------------------------------------------------------------------------------------------
    def element_jacobian(self, fp: ChainPass, point: np.ndarray | None = None, link: int | None = None) -> np.ndarray:
        """(N, 3, E) derivative of ``point`` (default the tool point) with respect to each elementary motion.

        With ``link=j`` the point is fixed in frame j: the motions beyond frame j do not move it, and the tool columns
        hold its derivative with respect to its own coordinates in frame j (the tool point's role for such a point).
        """
        p = (fp.point if point is None else point).T                                   # (3, N)
        R, t, loc = fp._R, fp._t, fp._local
        n, N = self.n, p.shape[-1]
        nb, nl = len(BASE_PARAMS), len(LINK_PARAMS)
        J = np.empty((N, 3, self.P))
        Jv = J.transpose(2, 1, 0)                                                      # (E, 3, N) view, written once
        # base: the measurement axes, then z, the yawed y and the base's x through the base origin
        Jv[:3] = np.eye(3)[:, :, None]
        arm = p - t[0]
        ax4 = np.stack([-np.sin(loc["base"][3]), np.cos(loc["base"][3]), 0.0 * loc["base"][3]])
        _cross_into(Jv[3], np.array([0.0, 0.0, 1.0])[:, None], arm)
        _cross_into(Jv[4], ax4.reshape(3, -1), arm)
        _cross_into(Jv[5], R[0, :, 0], arm)
        # links: theta about z_{j-1} through o_{j-1}; d along it; a along the x after theta; alpha about that x and
        # beta about y_j, both through o_j (j-1: the frame the link starts from, the previous one on a chain)
        lJ = Jv[nb:nb + nl * n].reshape(n, nl, 3, N)
        Rp, tp = (R[:-1], t[:-1]) if self.is_chain else (R[self.parent_frame], t[self.parent_frame])
        z = Rp[:, :, 2]
        u = Rp[:, :, 0] * loc["ct"][:, None] + Rp[:, :, 1] * loc["st"][:, None]
        arm_in, arm_out = p - tp, p - t[1:]
        _cross_into(lJ[:, 0], z, arm_in)
        lJ[:, 1] = z
        lJ[:, 2] = u
        _cross_into(lJ[:, 3], u, arm_out)
        _cross_into(lJ[:, 4], R[1:, :, 1], arm_out)
        frame = fp.point_frame if link is None else link
        if not (np.isscalar(frame) and frame == n and self.is_chain):
            # only the motions between the point's frame and the base move it
            nt = self._nontool
            if np.isscalar(frame):
                Jv[nt[~self.ancestors[frame][self.link_of[nt]]]] = 0.0
            else:
                Jv[nt] *= self.ancestors[frame][:, self.link_of[nt]].T[:, None, :]
        Rf, _ = _frame_at(R, t, frame)
        Jv[self._tool_cols] = Rf.transpose(1, 0, 2)                                   # d p_c / d p_k = R_f[c, k]
        return J

    def jacobians(self, q_rad: np.ndarray, params: np.ndarray | None = None):
        """Tool points (N, 3), their Jacobian w.r.t. every parameter (N, 3, P) and w.r.t. the joint angles (N, 3, n).

        Each parameter owns one elementary motion, so the parameter Jacobian *is* the element Jacobian; a joint angle
        moves the same element as its theta offset.
        """
        fp = self.forward(q_rad, params)
        J = self.element_jacobian(fp)
        return fp.point, J, J[:, :, self.joint_elements]


def kept_arrays(cache: dict, key, make, limit: int) -> tuple:
    """``cache[key]``, made by ``make()`` (a tuple of arrays, then read-only) when missing; the cache is emptied when
    it holds ``limit`` entries.  For what a pass derives from its inputs alone and a session asks again and again."""
    got = cache.get(key)
    if got is None:
        got = make()
        for a in got:
            a.flags.writeable = False
        if len(cache) >= limit:
            cache.clear()
        cache[key] = got
    return got


#: below this many poses a link step is one batched ``matmul`` (fewer numpy calls); above, rows of multiply-adds
SMALL_BATCH = 32


def _chain_step(R, t, A, off, R_out, t_out) -> None:
    """One link of the chain, pose-last: ``R_out = R A``, ``t_out = t + R off`` ((3, 3, N), (3, N)).

    The same product either way: for a handful of poses (a session's one pose at a time) as one batched matmul over
    pose-first views, where the per-call overhead dominates; for many, as three multiply-adds of contiguous rows,
    about twice as fast as ``matmul`` on stacks of 3x3."""
    if R.shape[-1] < SMALL_BATCH:
        Rp = R.transpose(2, 0, 1)
        np.matmul(Rp, A.transpose(2, 0, 1), out=R_out.transpose(2, 0, 1))
        np.add(t.T, np.matmul(Rp, off.T[:, :, None])[..., 0], out=t_out.T)
        return
    np.multiply(R[:, 0, None], A[0], out=R_out)
    R_out += R[:, 1, None] * A[1]
    R_out += R[:, 2, None] * A[2]
    t_out[:] = t + R[:, 0] * off[0] + R[:, 1] * off[1] + R[:, 2] * off[2]


def _twist_terms(ca, sa, cb, sb) -> tuple[np.ndarray, np.ndarray]:
    """What :func:`_link_rotations` takes from the links' twists alone: (cos beta, sin beta) and (sin beta, cos beta)
    (2, 1, 2, n, .) and the rotation's last row ``(-sin beta cos alpha, sin alpha, cos beta cos alpha)`` (n, 3, .)."""
    return np.stack([np.stack([cb, sb]), np.stack([sb, cb])])[:, None], np.stack([-sb * ca, sa, cb * ca], axis=1)


#: the signs of the second products of entries (0, 0), (0, 2), (1, 0), (1, 2) in :func:`_link_rotations`, and of the
#: entries (0, 1), (1, 1)
_SIGNS = np.array([[-1.0, 1.0], [1.0, -1.0]])[:, :, None, None]
_SIGNS_MID = np.array([-1.0, 1.0])[:, None, None]


def _link_rotations(cs, ca, sa, twist, row2) -> np.ndarray:
    """(n, 3, 3, N) every link's rotation ``Rz(theta) Rx(alpha) Ry(beta)`` from ``cs`` = (cos, sin) of theta (2, n, N).

    The entries are those of the closed form written entry by entry (``cb ct - sb (st sa)``, ``-st ca`` ...), the
    same products and sums of the same floats (a difference is a sum with the product negated, exactly), but computed
    a block at a time: about ten numpy calls instead of thirty, which is the cost of a pass over one pose."""
    n, N = cs.shape[1:]
    A = np.empty((n, 3, 3, N))
    first = cs[:, None] * twist[0]                           # [[ct cb, ct sb], [st cb, st sb]]
    second = (cs[::-1] * sa)[:, None] * twist[1]             # [[st sa sb, st sa cb], [ct sa sb, ct sa cb]]
    # (0, 0) cb ct - sb st sa, (0, 2) sb ct + cb st sa, (1, 0) cb st + sb ct sa, (1, 2) sb st - cb ct sa
    np.add(first, _SIGNS * second, out=A[:, :2, ::2].transpose(1, 2, 0, 3))
    np.multiply(_SIGNS_MID, cs[::-1] * ca, out=A[:, :2, 1].transpose(1, 0, 2))   # (0, 1) -st ca, (1, 1) ct ca
    A[:, 2] = row2
    return A


def _small_chain(R, t, A, off, parent: list, serial: bool) -> None:
    """Chain the links of a few poses (below :data:`SMALL_BATCH`): the products of :func:`_chain_step`'s matmul
    branch on the same pose-first views (so the same BLAS calls on the same strides, the same floats), with fewer
    numpy calls: the frames' rotations one matmul per link, then on a serial chain every link's offset turned into
    the measurement frame in one batched matmul and the origins summed link after link by one accumulate (the
    same additions in the same order)."""
    Rv, Av = R.transpose(0, 3, 1, 2), A.transpose(0, 3, 1, 2)                    # (n+1, N, 3, 3), (n, N, 3, 3)
    tv, offv = t.transpose(0, 2, 1), off.transpose(0, 2, 1)[..., None]          # (n+1, N, 3), (n, N, 3, 1)
    for j, p in enumerate(parent):
        np.matmul(Rv[p], Av[j], out=Rv[j + 1])
    if serial:
        tv[1:] = np.matmul(Rv[:-1], offv)[..., 0]
        np.add.accumulate(tv, axis=0, out=tv)
        return
    for j, p in enumerate(parent):
        np.add(tv[p], np.matmul(Rv[p], offv[j])[..., 0], out=tv[j + 1])


def _point_frames(frame, N: int, n: int):
    """A point's frame as given to :meth:`Kinematics.forward`: one int for every pose, or (N,) ints."""
    if np.isscalar(frame) or np.ndim(frame) == 0:
        f = int(frame)
        if not 0 <= f <= n:
            raise ValueError(f"frame index must be 0..{n}, got {frame!r}")
        return f
    f = np.asarray(frame, int)
    if f.shape != (N,) or f.min(initial=0) < 0 or f.max(initial=0) > n:
        raise ValueError(f"expected one frame index 0..{n} per pose ({N}), got shape {f.shape}")
    if N and np.all(f == f[0]):
        return int(f[0])
    return f


def _frame_at(R: np.ndarray, t: np.ndarray, frame) -> tuple[np.ndarray, np.ndarray]:
    """The frame ``frame`` (an int, or one per pose) of pose-last frames (F, 3, 3, N), (F, 3, N): (3, 3, N), (3, N)."""
    if np.isscalar(frame) or np.ndim(frame) == 0:
        return R[int(frame)], t[int(frame)]
    cols = np.arange(R.shape[-1])
    return R[frame, :, :, cols].transpose(1, 2, 0), t[frame, :, cols].T


def _cross_into(out: np.ndarray, a: np.ndarray, b: np.ndarray) -> None:
    """``out = a x b`` over axis -2 (pose-last vectors (..., 3, N), broadcast), written in place.

    For a few poses (below :data:`SMALL_BATCH`) the three components at once, from each operand written twice along
    that axis: the same products and differences of the same floats in fewer numpy calls (a session's predictor
    asks for one pose's Jacobian at a time; tests/test_model_small_paths.py)."""
    if out.shape[-1] < SMALL_BATCH:
        a2, b2 = np.concatenate((a, a), -2), np.concatenate((b, b), -2)
        np.subtract(a2[..., 1:4, :] * b2[..., 2:5, :], a2[..., 2:5, :] * b2[..., 1:4, :], out=out)
        return
    out[..., 0, :] = a[..., 1, :] * b[..., 2, :] - a[..., 2, :] * b[..., 1, :]
    out[..., 1, :] = a[..., 2, :] * b[..., 0, :] - a[..., 0, :] * b[..., 2, :]
    out[..., 2, :] = a[..., 0, :] * b[..., 1, :] - a[..., 1, :] * b[..., 0, :]


def _element_screws(fp: ChainPass) -> tuple[np.ndarray, np.ndarray]:
    """The axis and a point on the axis of every elementary motion (E, 3, N) each, from a pass's frames.

    Base ``Tx Ty Tz Rz Ry Rx``: the measurement axes, then z, the yawed y and the base's x, through the base origin.
    Link j ``Rz Tz Tx Rx Ry``: z of frame j-1 through its origin (theta, d); the x axis after the theta rotation
    (``R_{j-1} (cos theta, sin theta, 0)``) through the point d along z (a), and through frame j's origin (alpha);
    y of frame j through its origin (beta: the rotation before it leaves y alone).  Tool ``Tx Ty Tz``: frame n's
    axes."""
    loc, R, t = fp._local, fp._R, fp._t
    n, N = R.shape[0] - 1, R.shape[-1]
    nb, nl = len(BASE_PARAMS), len(LINK_PARAMS)
    E = nb + nl * n + len(TOOL_PARAMS)
    ax = np.empty((E, 3, N))
    org = np.empty((E, 3, N))
    base = loc["base"]
    ax[:3] = np.eye(3)[:, :, None]
    org[:3] = 0.0
    org[1:3, 0] = base[0]
    org[2, 1] = base[1]
    ax[3] = np.array([0.0, 0.0, 1.0])[:, None]
    ax[4, 0], ax[4, 1], ax[4, 2] = -np.sin(base[3]), np.cos(base[3]), 0.0
    ax[5] = R[0, :, 0]
    org[3:6] = t[0]
    lax = ax[nb:nb + nl * n].reshape(n, nl, 3, N)
    lorg = org[nb:nb + nl * n].reshape(n, nl, 3, N)
    pf = fp.parent_frame
    Rp, tp = R[pf], t[pf]                                                          # the frames the links start from
    z = Rp[:, :, 2]                                                                # (n, 3, N)
    lax[:, 0] = z
    lax[:, 1] = z
    lax[:, 2] = Rp[:, :, 0] * loc["ct"][:, None] + Rp[:, :, 1] * loc["st"][:, None]
    lax[:, 3] = lax[:, 2]
    lax[:, 4] = R[1:, :, 1]
    lorg[:, 0] = tp
    lorg[:, 1] = tp
    lorg[:, 2] = tp + z * loc["d"][:, None]
    lorg[:, 3] = t[1:]
    lorg[:, 4] = t[1:]
    f = nb + nl * n
    tool = loc["tool"]
    Rf, tf = _frame_at(R, t, fp.point_frame)
    ax[f:] = Rf.transpose(1, 0, 2)
    org[f] = tf
    org[f + 1] = tf + Rf[:, 0] * tool[0]
    org[f + 2] = org[f + 1] + Rf[:, 1] * tool[1]
    return ax, org

