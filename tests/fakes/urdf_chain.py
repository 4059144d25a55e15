"""An independent URDF chain for the tests: the file's joints read with ElementTree and multiplied as plain 4x4
matrices, sharing no code with robocal (it imports nothing from ``calib``).

Why: a test of the URDF import or export whose truth comes from robocal's own chain can only show that robocal agrees
with itself.  Here the URDF's own conventions are written again, as plainly as possible: a joint's child frame is
``parent @ Trans(xyz) @ Rz(yaw) @ Ry(pitch) @ Rx(roll) @ motion(q)``, a revolute joint turns about its ``axis``
(Rodrigues), a prismatic one slides along it, metres and radians in the file.  The rotations are the oracle's
(tests/fakes/oracle/chain.py).

:func:`perturbed` makes a "real robot" from a description: every moving joint's origin moved by a few mm and turned
by a few tenths of a degree (seeded), the way a built robot differs from its drawing.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from .oracle.chain import axis_angle, hom, rpy_matrix

__all__ = ["UrdfChain", "instrument", "perturbed", "rpy_matrix"]

MOVING = ("revolute", "continuous", "prismatic")


def _vec(text: str | None, default=(0.0, 0.0, 0.0)) -> np.ndarray:
    return np.array([float(v) for v in text.split()]) if text else np.array(default, float)


class UrdfChain:
    """The joints from ``base`` to ``tip`` of a URDF text; :meth:`tip_frames` in mm."""

    def __init__(self, text: str, base: str, tip: str):
        root = ET.fromstring(text)
        by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
        path, link = [], tip
        while link != base:
            j = by_child[link]
            path.append(j)
            link = j.find("parent").get("link")
        self.joints = path[::-1]
        self.moving = [j.get("name") for j in self.joints if j.get("type") in MOVING]

    def origin(self, j) -> np.ndarray:
        o = j.find("origin")
        xyz = _vec(o.get("xyz") if o is not None else None)
        rpy = _vec(o.get("rpy") if o is not None else None)
        return hom(rpy_matrix(*rpy), xyz * 1000.0)

    def tip_frames(self, q: np.ndarray) -> np.ndarray:
        """(N, 4, 4) the tip link's frame in the base link (mm) for joint values q (N, moving joints): rad, or m for
        a prismatic joint (the file's units)."""
        out = []
        for row in np.atleast_2d(q):
            T = np.eye(4)
            vals = dict(zip(self.moving, row))
            for j in self.joints:
                T = T @ self.origin(j)
                kind = j.get("type")
                if kind in MOVING:
                    ax = j.find("axis")
                    u = _vec(ax.get("xyz") if ax is not None else None, (1.0, 0.0, 0.0))
                    v = vals[j.get("name")]
                    if kind == "prismatic":
                        T = T @ hom(t=u / np.linalg.norm(u) * v * 1000.0)
                    else:
                        T = T @ hom(axis_angle(u, v))
            out.append(T)
        return np.array(out)

    def points(self, q: np.ndarray, on_tip_mm) -> np.ndarray:
        """(N, K, 3) points given on the tip link (K, 3), mm, in the base link."""
        F = self.tip_frames(q)
        p = np.atleast_2d(np.asarray(on_tip_mm, float))
        return np.einsum("nij,kj->nki", F[:, :3, :3], p) + F[:, None, :3, 3]


def perturbed(text: str, seed: int, mm: float = 2.0, deg: float = 0.3) -> str:
    """The URDF text with every moving joint's origin moved by up to ``mm`` and turned by up to ``deg`` (uniform,
    seeded): a robot as built."""
    rng = np.random.default_rng(seed)
    root = ET.fromstring(text)
    for j in root.findall("joint"):
        if j.get("type") not in MOVING:
            continue
        o = j.find("origin")
        if o is None:
            o = ET.SubElement(j, "origin")
        xyz = _vec(o.get("xyz")) + rng.uniform(-mm, mm, 3) / 1000.0
        rpy = _vec(o.get("rpy")) + np.radians(rng.uniform(-deg, deg, 3))
        o.set("xyz", " ".join(repr(float(v)) for v in xyz))
        o.set("rpy", " ".join(repr(float(v)) for v in rpy))
    return ET.tostring(root, encoding="unicode")


def instrument(points_mm: np.ndarray, T: np.ndarray, noise_mm: float, seed: int) -> np.ndarray:
    """Points (..., 3) seen from an instrument whose frame holds the base link at ``T``, with Gaussian noise."""
    rng = np.random.default_rng(seed)
    p = points_mm @ T[:3, :3].T + T[:3, 3]
    return p + rng.normal(0.0, noise_mm, p.shape)
