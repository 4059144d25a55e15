"""Set-up design for the Chapter 4 procedures: the thesis's trends (sections 5.2-5.4) and the search."""
import json
import subprocess
import sys

import numpy as np

from calib.setup_plan import Constraints, plan_sweep, ruler_errors, sweep_errors, te_errors

C = Constraints()


def test_gamma_errors_have_a_minimum_in_L():
    """Section 5.2: the error in gamma1, gamma2 has a minimum in the baseline L (ruler fixed)."""
    Ls = np.linspace(600, 3000, 13)
    for key in ("gamma1_deg", "gamma2_deg"):
        e = np.array([ruler_errors(L, 1860.0, 930.0, -300.0, 1200.0, C)[key] for L in Ls])
        k = int(np.argmin(e))
        assert 0 < k < len(Ls) - 1, (key, e)
        assert e[0] > 1.1 * e[k] and e[-1] > 1.1 * e[k]


def test_fig_5_4_magnitudes():
    """Fig 5.4 geometry, 3" readings: L to a few tenths of a mm, gamma to about a hundredth of a degree."""
    e = ruler_errors(1609.9, 1860.0, 930.0, -300.0, 1200.0, C)
    assert 0.05 < e["L_mm"] < 0.3
    assert 0.002 < e["gamma1_deg"] < 0.02 and 0.002 < e["gamma2_deg"] < 0.02


def test_link_parameter_errors_flatten_beyond_500_mm():
    """Section 5.3: link-parameter errors fall quickly with the radius of rotation, then flatten (~500 mm)."""
    r = np.array([100, 200, 300, 500, 700, 900, 1100])
    e = np.array([sweep_errors(x, (800.0, 2800.0, 0.0), C, axis=(0, 1, 0), span_deg=120)["link_mm"] for x in r])
    assert np.all(np.diff(e) < 0.01)
    early = (e[0] - e[3]) / (r[3] - r[0])
    late = (e[3] - e[-1]) / (r[-1] - r[3])
    assert early > 5 * late


def test_te_error_falls_with_target_spacing_and_grows_with_distance():
    """Section 5.4.1 (Fig 5.11): R_dj decreases the error rapidly then less; Y increases it monotonically."""
    rd = [50, 100, 200, 400, 800]
    e = [te_errors(x, (800.0, 2800.0, 0.0), C)["angle_deg"] for x in rd]
    assert all(a > b for a, b in zip(e, e[1:]))
    assert (e[0] - e[1]) > 5 * (e[3] - e[4])
    ys = [1000, 2000, 3000, 4000]
    ey = [te_errors(400, (800.0, y, 0.0), C)["angle_deg"] for y in ys]
    assert all(a < b for a, b in zip(ey, ey[1:]))


def test_search_beats_the_thesis_setup_and_respects_the_room():
    plan = plan_sweep(C, seed=1)
    v = plan.variables
    assert C.Rj_mm[0] <= v["Rj_mm"] <= C.Rj_mm[1]
    assert v["Yc_mm"] - v["Rj_mm"] >= C.min_focus_mm - 1e-6 and v["Yc_mm"] + v["Rj_mm"] <= C.room_y_mm + 1e-6
    thesis = sweep_errors(600.0, (474.9, 2853.0, 184.9), C, axis=(0, 1, 0))["link_mm"]
    assert plan.errors["link_mm"] < thesis


def test_plan_setup_command():
    r = subprocess.run([sys.executable, "-m", "app.cli", "plan", "setup", "ruler", "--json"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["procedure"] == "ruler" and 500 <= out["variables"]["L_mm"] <= 3000
    assert out["errors"]["robot_point_mm"] > 0
    r = subprocess.run([sys.executable, "-m", "app.cli", "plan", "setup", "ruler", "--room-y", "500"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "minimum focus" in r.stderr


def test_sweep_design_written_into_a_setup_keeps_its_robot(tmp_path):
    """The design written into a set-up describes that set-up: the joint centre where its robot base stands (not a
    centre the design chose and the file drops), only R_j designed, and the errors are those of that geometry."""
    centre = (475.0, 2853.0, 185.0)
    plan = plan_sweep(C, seed=1, centre_mm=centre)
    v = plan.variables
    assert (v["Xc_mm"], v["Yc_mm"], v["Zc_mm"]) == centre and C.Rj_mm[0] <= v["Rj_mm"] <= C.Rj_mm[1]
    assert plan.errors == sweep_errors(v["Rj_mm"], centre, C, axis=(0, 1, 0))
    assert plan.errors["link_mm"] <= sweep_errors(600.0, centre, C, axis=(0, 1, 0))["link_mm"] + 1e-9
    assert "fixed" in plan.note
    out = tmp_path / "s.json"
    r = subprocess.run([sys.executable, "-m", "app.cli", "plan", "setup", "sweep", "--out", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "given:" in r.stdout and "base" in r.stdout
    written = json.loads(out.read_text())
    d = written["design"]["sweep"]["variables"]
    assert [d["Xc_mm"], d["Yc_mm"], d["Zc_mm"]] == written["base_xyz_mm"]
    assert written["sweep_radius_mm"] == round(d["Rj_mm"], 0)
