"""A calibrated URDF: the description's own file with corrected joint origins, every other element kept.

How the corrections are found (from the model's frames, :mod:`calib.export.frames`):

* the base link is placed in the measurement frame so that the chain's frame 0 keeps its place in the base link
  (``B = W0 F0^-1``: what the data cannot tell apart -- the base link's pose and the first axis's -- goes to the base,
  which the side file holds);
* for each moving joint the URDF's joint frame ``F`` is rigid with the link that joint moves, so nominally
  ``F = D_k H`` with ``D_k`` the model's frame of that link and ``H`` constant; the calibrated frame is ``D'_k H``,
  turned by the smallest rotation that puts the joint's own axis vector on the calibrated axis and, for a revolute
  joint, moved onto the calibrated axis line.  The joint keeps its axis vector and its zero (the zero offset the fit
  found is a rotation of the frame about the axis, which is what a URDF origin can hold);
* fixed joints keep their origins; each moving joint's origin is its calibrated frame seen from its parent link's
  calibrated frame, so every axis of the written file is the calibrated one whatever the joint values;
* tool points are given on the tip link of the written file (side file).

The description is edited as XML (lxml keeps element order, attributes, comments and namespaces); only the
``xyz``/``rpy`` attributes of the moving joints' ``<origin>`` change.  A DH description has no URDF: :func:`dh_urdf`
writes one from the model's frames, and the same correction runs on it.
"""
from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import RobocalError
from .frames import axis_frame, frames_at_zero, homogeneous, moving_frame, rotation_taking, rpy_of
from ..names import joint_names

REVOLUTE = ("revolute", "continuous")
#: how far the description's chain may sit from its URDF before the export refuses (a different file was given)
MATCH_MM, MATCH_RAD = 1e-6, 1e-9


@dataclass
class UrdfSource:
    """The URDF a description comes from and the cut the robot was made with."""

    path: Path
    base_link: str | None = None
    tip_link: str | None = None
    point_links: dict[str, str] | None = None     # a description's points that name their own links (a tree)


def urdf_source(robot_arg, base_link: str | None = None, tip_link: str | None = None) -> UrdfSource | None:
    """The URDF behind a ``--robot`` argument: the file itself, or a calibration description's ``urdf = ...`` (the
    command line's cut wins over the file's); None for a DH description (or the default Puma)."""
    if robot_arg is None:
        return None
    base_link = base_link or getattr(robot_arg, "base_link", None)
    tip_link = tip_link or getattr(robot_arg, "tip_link", None)
    path = Path(str(robot_arg))
    if path.suffix.lower() == ".urdf":
        return UrdfSource(path, base_link, tip_link)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None                                   # load_robot has already said what is wrong with it
    if "urdf" not in data:
        return None
    urdf = Path(data["urdf"])
    points = (data.get("tool") or {}).get("points") or {}
    links = {k: v["link"] for k, v in points.items() if isinstance(v, dict) and isinstance(v.get("link"), str)}
    return UrdfSource(urdf if urdf.is_absolute() else path.parent / urdf,
                      base_link or data.get("base_link") or None, tip_link or data.get("tip_link") or None,
                      links or None)


def _mm(T: np.ndarray) -> np.ndarray:
    T = np.array(T, float)
    T[:3, 3] *= 1000.0
    return T


class _LinkFrames:
    """Frames of the URDF's links at zero joint values in the base link (mm), walking parent joints up to the base;
    ``moved`` replaces the frame of a moving joint's child (the calibrated one)."""

    def __init__(self, tree, base_link: str, moved: dict[str, np.ndarray] | None = None):
        self.tree, self.base, self.moved = tree, base_link, moved or {}
        self._cache: dict[str, np.ndarray] = {base_link: np.eye(4)}

    def __call__(self, link: str) -> np.ndarray:
        if link not in self._cache:
            if link in self.moved:
                self._cache[link] = self.moved[link]
            else:
                j = self.tree.child_joint.get(link)
                if j is None:
                    raise RobocalError(f"{self.tree.source}: link {link!r} is not below the base link {self.base!r}")
                self._cache[link] = self(j.parent) @ _mm(j.origin)
        return self._cache[link]


@dataclass
class Corrections:
    """What the export computed: new origins (joint name -> 4x4, mm), the base link in the measurement frame, each
    tool point on its link of the written file (the tip link of a chain), and per joint how far its frame moved."""

    origins: dict[str, np.ndarray]
    base_in_measurement: np.ndarray
    tool_points_on_links: dict[str, np.ndarray]
    tip_link: str
    point_links: dict[str, str] = field(default_factory=dict)     # tool point -> the link it is given on
    moved_mm: dict[str, float] = field(default_factory=dict)
    turned_rad: dict[str, float] = field(default_factory=dict)


def corrected_origins(tree, base_link: str, point_links: dict[str, str], nominal, calibrated) -> Corrections:
    """The origins of the moving joints of ``nominal`` (a robot imported from ``tree``: a chain, or the tree to the
    links of ``point_links``, tool point -> link) that make the URDF's joint frames coincide with the axes of
    ``calibrated`` (the same robot with identified parameters).  A tree's branch and fixed links are no URDF joint:
    each URDF joint is placed from its own link's frames (the frame it turns about, the frame that moves with it)."""
    Wn, Wc = frames_at_zero(nominal), frames_at_zero(calibrated)
    F0 = np.asarray(nominal.frame0_in_base, float)
    Bn, Bc = Wn[0] @ np.linalg.inv(F0), Wc[0] @ np.linalg.inv(F0)
    Dn, Dc = np.linalg.inv(Bn) @ Wn, np.linalg.inv(Bc) @ Wc            # in the base link
    nominal_links = _LinkFrames(tree, base_link)
    new_frames: dict[str, np.ndarray] = {}
    moving = {}
    for k, name in enumerate(nominal.joint_names):
        if nominal.variable_of[k] != k:                                 # a branch or fixed link of a tree
            continue
        j = tree.joints[name]
        moving[name] = j
        F = nominal_links(j.child)
        _check_axis(tree, j, F, Dn[axis_frame(nominal, k)])
        H = np.linalg.inv(Dn[moving_frame(k)]) @ F
        new_frames[j.child] = _onto_axis(Dc[moving_frame(k)] @ H, j, Dc[axis_frame(calibrated, k)])
    links = _LinkFrames(tree, base_link, new_frames)
    origins = {name: np.linalg.inv(links(j.parent)) @ new_frames[j.child] for name, j in moving.items()}
    tool, on = {}, {}
    for name, p in calibrated.tool_points_mm.items():
        link = point_links[name]
        world = Dc[calibrated.point_frame(name)] @ np.append(np.asarray(p, float), 1.0)
        tool[name], on[name] = (np.linalg.inv(links(link)) @ world)[:3], link
    moved = {name: float(np.linalg.norm(new_frames[j.child][:3, 3] - nominal_links(j.child)[:3, 3]))
             for name, j in moving.items()}
    turned = {name: _angle(new_frames[j.child][:3, :3], nominal_links(j.child)[:3, :3]) for name, j in moving.items()}
    tip = list(on.values())[-1] if on else base_link
    return Corrections(origins, Bc, tool, tip, on, moved, turned)


def _angle(Ra: np.ndarray, Rb: np.ndarray) -> float:
    c = (np.trace(Ra.T @ Rb) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))


def _onto_axis(T: np.ndarray, j, D_axis: np.ndarray) -> np.ndarray:
    """``T`` turned (smallest rotation) so that joint ``j``'s axis vector lies along ``D_axis``'s z, and for a revolute
    joint moved onto that axis line (a prismatic joint's axis is a direction only)."""
    u = D_axis[:3, 2]
    R = rotation_taking(T[:3, :3] @ j.axis, u) @ T[:3, :3]
    t = T[:3, 3]
    if j.type in REVOLUTE:
        o = D_axis[:3, 3]
        t = o + u * float(np.dot(t - o, u))
    return homogeneous(R, t)


def _check_axis(tree, j, F: np.ndarray, D_axis: np.ndarray) -> None:
    """The description's chain must be this URDF's: joint ``j``'s axis where the model's frame puts it."""
    u = F[:3, :3] @ j.axis
    off_dir = float(np.linalg.norm(np.cross(u, D_axis[:3, 2])))
    d = F[:3, 3] - D_axis[:3, 3]
    off_line = float(np.linalg.norm(d - np.dot(d, u) * u)) if j.type in REVOLUTE else 0.0
    if off_dir > MATCH_RAD * 1e3 or off_line > MATCH_MM * 1e3 or float(np.dot(u, D_axis[:3, 2])) < 0:
        raise RobocalError(f"{tree.where('joint', j.name)}: the robot's axis of this joint is not the URDF's "
                           f"({off_dir:.3g} rad, {off_line:.3g} mm apart): the description was not made from this file")


# -- the XML --------------------------------------------------------------------------------------------------------
def _num(x: float) -> str:
    """15 significant digits (1e-12 mm on a metre: far inside the read-back check, also near pitch +-90 deg where
    roll and yaw cancel), rounding noise shown as 0."""
    x = float(x)
    return "0" if abs(x) < 1e-13 else f"{x:.15g}"


def rewrite(urdf_path: Path, origins: dict[str, np.ndarray], comment: str | None = None) -> str:
    """The URDF text with the ``<origin>`` of the named joints replaced (xyz in m, rpy in rad), all else kept."""
    # lxml (~20 ms) is loaded only when a URDF is rewritten
    from lxml import etree
    try:
        doc = etree.parse(str(urdf_path), etree.XMLParser(remove_blank_text=False, remove_comments=False))
    except (OSError, etree.XMLSyntaxError) as exc:
        raise RobocalError(f"{urdf_path}: not a readable URDF: {exc}") from None
    root = doc.getroot()
    by_name = {el.get("name"): el for el in root if el.tag == "joint"}
    for name, T in origins.items():
        el = by_name[name]
        origin = el.find("origin")
        if origin is None:
            origin = etree.Element("origin")
            origin.tail = el.text
            el.insert(0, origin)
        origin.set("xyz", " ".join(_num(v / 1000.0) for v in T[:3, 3]))
        origin.set("rpy", " ".join(_num(v) for v in rpy_of(T[:3, :3])))
    if comment:
        c = etree.Comment(f" {comment} ")
        c.tail = root.text
        root.insert(0, c)
    # what precedes the root (comments, processing instructions) one per line, as the file had it
    prolog = [etree.tostring(el, encoding="unicode", with_tail=False)
              for el in reversed(list(root.itersiblings(preceding=True)))]
    body = etree.tostring(root, encoding="unicode")
    # the declaration and the root's start tag as the file wrote them (lxml puts namespace declarations first)
    original = urdf_path.read_text(encoding="utf-8", errors="replace")
    decl = re.match(r"\s*(<\?xml[^>]*\?>)", original)
    start = re.search(rf"<{re.escape(root.tag)}\b[^>]*>", original)
    if start and not start.group(0).endswith("/>"):
        body = re.sub(rf"<{re.escape(root.tag)}\b[^>]*>", lambda _: start.group(0), body, count=1)
    head = (decl.group(1) if decl else f'<?xml version="{doc.docinfo.xml_version or "1.0"}"?>') + "\n"
    return head + "".join(p + "\n" for p in prolog) + body + "\n"


def dh_urdf(robot, name: str | None = None) -> tuple[str, Corrections]:
    """A URDF of a DH description (the calibrated one), made from its frames at zero: link ``k`` hangs from joint
    ``k`` (z axis), the flange link is frame n; masses with their centres, limits from the description (no drive
    limits are known: effort and velocity 0).  Returns the text and what the side file needs (base, tool points)."""
    # xml.sax.saxutils loads urllib.request (~40-80 ms); only writing a URDF needs it
    from xml.sax.saxutils import quoteattr
    W = frames_at_zero(robot)
    F0 = np.asarray(robot.frame0_in_base, float)
    D = np.linalg.inv(W[0] @ np.linalg.inv(F0)) @ W                    # in the description's base frame
    names = list(joint_names(robot))
    tip = "flange" if "flange" not in names else "flange_link"
    links = ["base_link"] + [f"{j}_link" for j in names] + [tip]
    out = ['<?xml version="1.0" encoding="utf-8"?>', f'<robot name={quoteattr(name or robot.name)}>',
           f'  <!-- made by robocal from the calibrated DH description {robot.source}: joint k turns about the z axis '
           'of its frame; no drive limits are known (effort, velocity 0) and no inertia tensors (masses and '
           'centres only) -->', '  <link name="base_link"/>']
    parent_frame = np.eye(4)
    for k, jn in enumerate(names):
        frame = D[axis_frame(robot, k)]
        origin = np.linalg.inv(parent_frame) @ frame
        kind = "prismatic" if robot.prismatic[k] else "revolute"
        scale = 0.001 if robot.prismatic[k] else 1.0
        lo, hi = (float(v) * scale for v in robot.limits_rad[k])
        inertial = ""
        if robot.mass_kg[k] > 0:
            com = (np.linalg.inv(frame) @ D[moving_frame(k)] @ np.append(robot.com_mm[k], 1.0))[:3] / 1000.0
            inertial = (f'\n    <inertial><origin xyz="{" ".join(_num(v) for v in com)}" rpy="0 0 0"/>'
                        f'<mass value="{_num(robot.mass_kg[k])}"/>'
                        '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>\n  ')
        out += [f'  <link name="{links[k + 1]}">{inertial}</link>' if inertial else f'  <link name="{links[k + 1]}"/>',
                f'  <joint name={quoteattr(jn)} type="{kind}">',
                f'    <parent link="{links[k]}"/>', f'    <child link="{links[k + 1]}"/>',
                f'    <origin xyz="{" ".join(_num(v / 1000.0) for v in origin[:3, 3])}" '
                f'rpy="{" ".join(_num(v) for v in rpy_of(origin[:3, :3]))}"/>',
                '    <axis xyz="0 0 1"/>',
                f'    <limit lower="{_num(lo)}" upper="{_num(hi)}" effort="0" velocity="0"/>',
                '  </joint>']
        parent_frame = frame
    n = len(names)
    flange = np.linalg.inv(parent_frame) @ D[moving_frame(n - 1)]
    out += [f'  <link name="{tip}"/>', f'  <joint name="{tip}_fixed" type="fixed">',
            f'    <parent link="{links[n]}"/>', f'    <child link="{tip}"/>',
            f'    <origin xyz="{" ".join(_num(v / 1000.0) for v in flange[:3, 3])}" '
            f'rpy="{" ".join(_num(v) for v in rpy_of(flange[:3, :3]))}"/>', '  </joint>', '</robot>']
    tool = {k: np.asarray(v, float).copy() for k, v in robot.tool_points_mm.items()}
    return "\n".join(out) + "\n", Corrections({}, W[0] @ np.linalg.inv(F0), tool, tip, {k: tip for k in tool})
