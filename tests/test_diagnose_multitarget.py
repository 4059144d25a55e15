"""Diagnosis of a pose CSV with several targets per pose (``pose`` and ``target`` columns), against truth made elsewhere.

The data come from the independent generator in tests/fakes/thesis_puma.py (plain numpy products of the thesis's
formulas, nothing from calib): a Puma whose geometry is off its description (zero offsets, link lengths, base),
carrying three reflectors at different places on the flange, measured with known Gaussian noise, with or without one
running error the geometric model lacks.  Each target must be its own tool point (as identify models them), so
that the clean data reach the noise floor, the withheld effect is named on its joint, and identify and diagnose
give the same geometric fit on the same file.
"""
from __future__ import annotations

import dataclasses
import json
from importlib import resources

import numpy as np
import pytest

from app.cli import main
from tests.fakes.thesis_puma import JointCompliance, ThesisPuma, TransmissionError, base_matrix, true_points

PUMA_TOML = resources.files("calib") / "data" / "puma560.toml"
#: reflectors on the flange: position in frame 6 (mm)
TARGETS = {"R1": (0.0, 0.0, 60.0), "R2": (80.0, 0.0, 40.0), "R3": (-30.0, 90.0, 30.0)}
SIGMA_MM = 0.03
N_POSES = 60
WITHHELD = {"clean": (), "compliance_j3": (JointCompliance(3, 2e4),),
            "transmission_j4": (TransmissionError(4, 1.0, 0.002, 0.0005),)}


def _arm() -> ThesisPuma:
    """The fake Puma with a geometry that differs from its description (what the geometric fit must find)."""
    arm = ThesisPuma.from_toml(PUMA_TOML)
    return dataclasses.replace(arm, theta_offset=np.array([0.002, -0.003, 0.001, 0.004, -0.002, 0.003]),
                               a_mm=arm.a_mm + np.array([0.0, 0.4, -0.3, 0.0, 0.0, 0.0]),
                               base=base_matrix((1500.0, 800.0, -300.0), 0.3, 0.01, -0.02))


def _write(tmp_path, case: str, seed: int = 0, order=tuple(TARGETS)) -> tuple[str, str]:
    """The long pose CSV (one row per pose and target) and a description naming the reflectors as tool points."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.4, 1.4, (N_POSES, 6))
    arm = _arm()
    pts = {t: true_points(dataclasses.replace(arm, tool_xyz_t=tuple(-np.array(TARGETS[t]))), q, WITHHELD[case])[0]
           + rng.normal(0.0, SIGMA_MM, (N_POSES, 3)) for t in TARGETS}
    lines = ["pose,target," + ",".join(f"q{j}" for j in range(1, 7)) + ",x,y,z"]
    for i in range(N_POSES):
        for t in order:
            lines.append(f"p{i},{t}," + ",".join(f"{v:.9f}" for v in np.degrees(q[i])) + ","
                         + ",".join(f"{v:.6f}" for v in pts[t][i]))
    csv = tmp_path / f"{case}_{seed}_{''.join(order)}.csv"
    csv.write_text("\n".join(lines) + "\n", encoding="utf-8")
    desc = tmp_path / "puma_reflectors.toml"
    desc.write_text(PUMA_TOML.read_text(encoding="utf-8") + "".join(
        f"{t} = [{', '.join(str(v) for v in p)}]\n" for t, p in TARGETS.items()), encoding="utf-8")
    return str(csv), str(desc)


def _diagnose(csv: str, desc: str):
    from calib.diagnose import diagnose, load_data
    from calib.loading import load_robot
    return diagnose(load_data(csv, load_robot(desc), noise_mm=SIGMA_MM))


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    csv, desc = _write(tmp_path_factory.mktemp("multitarget"), "clean")
    return csv, desc, _diagnose(csv, desc)


def test_clean_data_reach_the_noise_floor_with_no_finding(clean):
    _, _, diag = clean
    assert diag.selection.findings == []
    assert diag.baseline_rms_mm < 1.1 * diag.heldout_floor_mm, (diag.baseline_rms_mm, diag.heldout_floor_mm)
    assert diag.geometric.all_fit.reduced_chi2 < 1.3
    # the model-free estimate from the targets' distances, next to the diagnosis
    assert not diag.noise.upper_bound and "target distances" in diag.noise.how
    assert abs(diag.noise.estimated_mm / SIGMA_MM - 1) < 0.3


def test_each_target_is_its_own_tool_point_on_the_flange(clean):
    """The reflectors' offsets from the reference one, as fitted, against the generator's (frame 6, mm).  A joint-6
    zero offset turns every tool point about z6 alike and cannot be told from it (the fit holds it), so what is
    compared is what that turn leaves: each offset's z and its length across z."""
    _, _, diag = clean
    fit = diag.geometric.all_fit
    names = list(diag.data.robot.tool_points_mm)
    assert names[0] == "R1" and sorted(names) == sorted(TARGETS)
    for k, t in enumerate(names[1:], start=1):
        truth = np.array(TARGETS[t]) - np.array(TARGETS["R1"])
        d = np.array([fit.value(f"target_offset.t{k}.d{a}_mm") for a in "xyz"])
        s = np.array([fit.std(f"target_offset.t{k}.d{a}_mm") for a in "xyz"])
        assert abs(d[2] - truth[2]) < 4 * s[2], (t, d, truth)
        assert abs(np.hypot(*d[:2]) - np.hypot(*truth[:2])) < 4 * np.hypot(*s[:2]), (t, d, truth)


@pytest.mark.parametrize("case, kind, joint", [("compliance_j3", "joint_compliance", 3),
                                               ("transmission_j4", "transmission_error", 4)])
def test_the_withheld_effect_is_named_on_its_joint(tmp_path, case, kind, joint):
    diag = _diagnose(*_write(tmp_path, case, seed=1))
    found = [(f.candidate.kind, f.candidate.joint) for f in diag.selection.findings]
    assert found and found[0] == (kind, joint), found
    assert diag.final_rms_mm < 1.1 * diag.heldout_floor_mm, (diag.final_rms_mm, diag.heldout_floor_mm)


def test_identify_and_diagnose_give_the_same_geometric_fit(clean, capsys):
    csv, desc, diag = clean
    # the same free set as the diagnosis's geometric baseline (identify's model selection would hold some)
    assert main(["identify", csv, "--robot", desc, "--noise-mm", str(SIGMA_MM), "--json", "--select", "all"]) == 0
    ident = {p["name"]: p for p in json.loads(capsys.readouterr().out)["parameters"]}
    fit = diag.geometric.all_fit
    for name in ("j2.a_mm", "j3.a_mm", "j2.theta_offset_rad", "j4.theta_offset_rad", "base.x_mm", "tool.z_mm",
                 "target_offset.t1.dx_mm", "target_offset.t2.dy_mm"):
        p = ident[name]
        assert p["estimated"] and name in fit.free
        assert abs(fit.value(name) - p["value"]) < 0.1 * p["error"], (name, fit.value(name), p["value"], p["error"])
        assert fit.std(name) == pytest.approx(p["error"], rel=0.05)


def test_the_command_diagnoses_the_file(clean, capsys):
    """The command's exit code and JSON (it stopped with an impossibly large chi-square before)."""
    csv, desc, _ = clean
    assert main(["diagnose", csv, "--robot", desc, "--noise-mm", str(SIGMA_MM), "--json", "--max-effects", "0"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["findings"] == [] and out["final_rms_mm"] < 1.1 * out["heldout_floor_mm"]
    assert out["noise_estimated_mm"] == pytest.approx(SIGMA_MM, rel=0.3)


def test_confirm_matches_targets_by_name(clean, tmp_path):
    """OTHER lists the targets in another order: its rows still meet their own tool points."""
    from calib.diagnose import load_data
    from calib.diagnose.confirm import confirm

    _, desc, diag = clean
    csv2, _ = _write(tmp_path, "clean", seed=5, order=("R3", "R2", "R1"))
    c = confirm(diag, load_data(csv2, diag.data.robot, noise_mm=SIGMA_MM))
    assert c.steps[0][1] < 1.2 * c.floor_mm, (c.steps, c.floor_mm)
