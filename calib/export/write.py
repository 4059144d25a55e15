"""``--out-urdf``: write the calibrated URDF and its side file, read the URDF back and check it (the one entry point
identify and reprocess call)."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import RobocalError
from ..fileio import atomic_path, atomic_write_text
from .check import TOLERANCE_MM, check_poses, reload_max_mm
from .side import not_in_urdf, side_document
from .urdf_out import UrdfSource, corrected_origins, dh_urdf, rewrite
from ..compensate import robot_from_theta
from ..urdf import analyse_chain, analyse_tree, read_urdf


@dataclass
class UrdfExport:
    urdf: str
    side: str
    n_origins: int
    check_mm: float
    n_poses: int
    poses: str                   # what the check ran on ("fitted poses" / "random configurations")
    not_in_urdf: str

    def lines(self) -> list[str]:
        what = f"{self.n_origins} joint origins corrected" if self.n_origins else "written from the model's frames"
        return [f"URDF written: {self.urdf} ({what}); read back, its forward kinematics equals the calibrated "
                f"model's on the {self.n_poses} {self.poses} to {self.check_mm:.1g} mm (max; limit {TOLERANCE_MM:g})",
                f"not in the URDF ({self.side}): {self.not_in_urdf}"]


def side_path(out: str | Path) -> Path:
    """The side file beside ``FILE.urdf``: ``FILE.side.json``."""
    p = Path(out)
    return p.with_name((p.stem if p.suffix.lower() == ".urdf" else p.name) + ".side.json")


def write_calibrated_urdf(out: str | Path, source: UrdfSource | None, model, theta: np.ndarray, sigma: np.ndarray,
                          q_check: np.ndarray | None = None, made_by: str = "robocal") -> UrdfExport:
    """Write ``out`` (the calibrated URDF) and its side file from the model's geometric parameters ``theta[:P]``;
    refuse (one line, nothing written) when the file read back does not reproduce the model."""
    nominal = model.robot
    calibrated = robot_from_theta(model, np.asarray(theta, float))
    readings = None
    if source is not None:
        tree = read_urdf(source.path)
        if source.point_links and not source.tip_link:      # a tree: the paths to every point's link
            links = {k: source.point_links.get(k) for k in nominal.tool_points_mm}
            chain = analyse_tree(tree, source.base_link, list(dict.fromkeys(links.values())))
        else:
            chain = analyse_chain(tree, source.base_link, source.tip_link)
            links = {k: chain.tip_link for k in nominal.tool_points_mm}
        base = chain.base_link
        corr = corrected_origins(tree, base, links, nominal, calibrated)
        text = rewrite(source.path, corr.origins, f"joint origins calibrated by {made_by}; what a URDF cannot hold "
                                                  f"is in {side_path(out).name}")
        made_from, readings = str(source.path), chain.reading_matrix
    else:
        text, corr = dh_urdf(calibrated, nominal.name)
        base, made_from = "base_link", nominal.source
    q = check_poses(calibrated, q_check)
    with atomic_path(out, ".urdf") as tmp:
        tmp.write_text(text, encoding="utf-8")
        worst = reload_max_mm(tmp, base, corr.point_links, corr.tool_points_on_links, corr.base_in_measurement,
                              calibrated, q)
        if not worst <= TOLERANCE_MM:
            raise RobocalError(f"{out}: not written: read back, its forward kinematics differs from the calibrated "
                               f"model's by {worst:.3g} mm (limit {TOLERANCE_MM:g} mm)")
    poses = "fitted poses" if q_check is not None and len(q_check) else "random configurations inside the limits"
    check = {"max_mm": worst, "n_poses": len(q), "poses": poses, "tolerance_mm": TOLERANCE_MM}
    doc = side_document(model, np.asarray(theta, float), np.asarray(sigma, float), corr, Path(out).name, made_from,
                        base, check, readings)
    side = side_path(out)
    atomic_write_text(side, json.dumps(doc, indent=1) + "\n")
    return UrdfExport(str(out), str(side), len(corr.origins), worst, len(q), poses, not_in_urdf(doc))
