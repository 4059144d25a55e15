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
math.  Poses are the leading axis of every array; the only Python loop is over the ~40 elements of the chain.

Units: mm and radians.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .robot import Robot

TX, TY, TZ, RX, RY, RZ = range(6)
_AXIS = {TX: 0, TY: 1, TZ: 2, RX: 0, RY: 1, RZ: 2}

#: per-link parameter names, in chain order, with their elementary motion
LINK_PARAMS = (("theta_offset_rad", RZ), ("d_mm", TZ), ("a_mm", TX), ("alpha_rad", RX), ("beta_rad", RY))
BASE_PARAMS = (("x_mm", TX), ("y_mm", TY), ("z_mm", TZ), ("yaw_rad", RZ), ("pitch_rad", RY), ("roll_rad", RX))
TOOL_PARAMS = (("x_mm", TX), ("y_mm", TY), ("z_mm", TZ))


@dataclass
class ChainPass:
    """Everything one forward pass computes, for N poses of an n-joint robot.  All in the measurement frame."""

    point: np.ndarray          # (N, 3) tool point
    frame_R: np.ndarray        # (N, n+1, 3, 3) frames 0..n (frame 0 = robot base after the base transform)
    frame_t: np.ndarray        # (N, n+1, 3)
    elem_axis: np.ndarray      # (N, E, 3) world direction of each elementary motion's axis
    elem_origin: np.ndarray    # (N, E, 3) a point on that axis (the frame origin before the motion)
    point_link: int | None = None   # frame the evaluated point is fixed in (None: the tool point, beyond frame n)
    gravity_m_s2: np.ndarray | None = None   # (3,) the description's gravity, in frame 0

    def gravity(self) -> np.ndarray:
        """(N, 3) gravity (m/s^2) in the measurement frame: the description's, given in frame 0, carried by the base.
        The one source of the gravity direction for loads and effects (a wall- or ceiling-mounted robot's
        description says where down is)."""
        if self.gravity_m_s2 is None:
            raise ValueError("a chain pass built without the description's gravity (Kinematics.forward sets it)")
        return self.frame_R[:, 0] @ self.gravity_m_s2

    @property
    def joint_axis(self) -> np.ndarray:
        """(N, n, 3) unit axis of each joint (z of frame j-1)."""
        return self.frame_R[:, :-1, :, 2]

    @property
    def joint_origin(self) -> np.ndarray:
        """(N, n, 3) origin of frame j-1, a point on joint j's axis."""
        return self.frame_t[:, :-1, :]

    def link_beam(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """(start, end) (N, 3) each: the body of link j as a beam for bending, clamped at joint j's axis.

        Frame j-1 to frame j is an offset d_j along joint j's axis then the link's length a_j across it; the beam is
        the part across the axis (from the foot of frame j's origin on the axis) -- the part along the axis is the
        joint's own offset -- unless the link has no length across (a_j ~ 0: then the whole offset is the body)."""
        start, end = self.frame_t[:, j - 1], self.frame_t[:, j]
        z = self.frame_R[:, j - 1, :, 2]
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
    def forward(self, q_rad: np.ndarray, params: np.ndarray | None = None) -> ChainPass:
        """Run the chain for joint angles ``q_rad`` (N, n)."""
        q = np.atleast_2d(np.asarray(q_rad, float))
        if q.shape[-1] != self.n:
            raise ValueError(f"expected {self.n} joint angles per pose, got {q.shape[-1]}")
        N = q.shape[0]
        p = self.nominal if params is None else np.asarray(params, float)
        vals = np.broadcast_to(p, (N, self.P)).copy()
        vals[:, self.joint_elements] += q
        E = self.P
        R = np.broadcast_to(np.eye(3), (N, 3, 3)).copy()
        t = np.zeros((N, 3))
        axes = np.empty((N, E, 3))
        origins = np.empty((N, E, 3))
        frame_R = np.empty((N, self.n + 1, 3, 3))
        frame_t = np.empty((N, self.n + 1, 3))
        link_end = {first + len(LINK_PARAMS) - 1: j + 1 for j, first in enumerate(self.link_first_element)}
        base_end = len(BASE_PARAMS) - 1
        for e in range(E):
            kind = self.kinds[e]
            k = _AXIS[kind]
            v = vals[:, e]
            axes[:, e] = R[:, :, k]
            origins[:, e] = t
            if kind <= TZ:
                t = t + R[:, :, k] * v[:, None]
            else:
                i, j = [(1, 2), (2, 0), (0, 1)][k]     # the two columns a rotation about axis k mixes
                c, s = np.cos(v)[:, None], np.sin(v)[:, None]
                ci, cj = R[:, :, i].copy(), R[:, :, j]
                R[:, :, i] = ci * c + cj * s
                R[:, :, j] = cj * c - ci * s
            if e == base_end:
                frame_R[:, 0], frame_t[:, 0] = R, t
            elif e in link_end:
                frame_R[:, link_end[e]], frame_t[:, link_end[e]] = R, t
        return ChainPass(point=t, frame_R=frame_R, frame_t=frame_t, elem_axis=axes, elem_origin=origins,
                         gravity_m_s2=np.asarray(self.robot.gravity_m_s2, float))

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
        p = np.broadcast_to(np.asarray(point_mm, float), t.shape)
        return t + np.einsum("nkij,nkj->nki", R, p)

    # -- Jacobians ------------------------------------------------------------------------------------------------
    def element_jacobian(self, fp: ChainPass, point: np.ndarray | None = None, link: int | None = None) -> np.ndarray:
        """(N, 3, E) derivative of ``point`` (default the tool point) with respect to each elementary motion.

        With ``link=j`` the point is fixed in frame j: the motions beyond frame j do not move it, and the tool columns
        hold its derivative with respect to its own coordinates in frame j (the tool point's role for such a point).
        """
        p = fp.point if point is None else point
        J = fp.elem_axis.copy()
        rot = self.kinds >= RX
        J[:, rot] = np.cross(fp.elem_axis[:, rot], p[:, None, :] - fp.elem_origin[:, rot])
        if link is not None:
            J[:, self.link_of > link] = 0.0
            tool = slice(self.index["tool.x_mm"], self.index["tool.z_mm"] + 1)
            J[:, tool] = fp.frame_R[:, link].transpose(0, 2, 1)           # row c = d p / d p_c = column c of R_j
        return J.transpose(0, 2, 1)

    def jacobians(self, q_rad: np.ndarray, params: np.ndarray | None = None):
        """Tool points (N, 3), their Jacobian w.r.t. every parameter (N, 3, P) and w.r.t. the joint angles (N, 3, n).

        Each parameter owns one elementary motion, so the parameter Jacobian *is* the element Jacobian; a joint angle
        moves the same element as its theta offset.
        """
        fp = self.forward(q_rad, params)
        J = self.element_jacobian(fp)
        return fp.point, J, J[:, :, self.joint_elements]
