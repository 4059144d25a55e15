"""The data's own split: the test rows are seen once, at the end (issue 24, item 1), and the ladder (item 3).

Every choice of the diagnosis -- outlier decision, noise estimate, geometry level, candidate effects, stopping -- is
made on the fit rows (with folds of their own).  So moving every test row by 50 mm changes the held-out figures and
nothing else; and the reported held-out figure is what a plain refit of the chosen model on the fit rows gives on
the test rows.
"""
import numpy as np
import pytest

from calib.diagnose import diagnose
from sim.validate import Case, make_case_data
from calib.identify import identify


@pytest.fixture(scope="module")
def split_data():
    d, _ = make_case_data(Case("joint_compliance", 3, None, 4.0, seed=12, n_poses=90))
    d.split = ["test" if i % 3 == 2 else "fit" for i in range(d.n)]
    return d


@pytest.fixture(scope="module")
def diag(split_data):
    return diagnose(split_data, level="full")


def _shifted(d):
    out = d.subset(np.arange(d.n))
    test = np.asarray(d.split) == "test"
    out.points_mm = d.points_mm.copy()
    out.points_mm[test, 0] += 50.0
    return out


def test_test_rows_change_the_held_out_figures_and_nothing_else(split_data, diag):
    a = diag
    b = diagnose(_shifted(split_data), level="full")
    ja, jb = a.to_json(), b.to_json()
    assert [f["label"] for f in ja["findings"]] == ["joint_compliance j3"]
    assert ja["findings"] == jb["findings"]
    np.testing.assert_array_equal(a.selection.final.all_fit.theta, b.selection.final.all_fit.theta)
    for key in ("outliers", "noise_estimate", "geometry_level", "stop_reason", "rounds", "baseline_rms_mm"):
        assert ja[key] == jb[key], key
    assert [s["n_params"] for s in ja["ladder"]] == [s["n_params"] for s in jb["ladder"]]
    assert ja["after"]["mean_mm"] < 1.0 < 40.0 < jb["after"]["mean_mm"]      # what the test rows say did move


def test_held_out_figure_is_a_plain_refit_on_the_fit_rows(split_data, diag):
    j = diag.to_json()
    fit = np.flatnonzero(np.asarray(split_data.split) == "fit")
    test = np.flatnonzero(np.asarray(split_data.split) == "test")
    final = diag.selection.final
    model = final.model
    plain = identify(model, split_data.observations(fit), free=list(final.all_fit.free), outliers="off")
    t = split_data.subset(test)
    err = np.linalg.norm(t.points_mm - model.points(t.q_rad, t.ctx, plain.theta[: model.P]), axis=1)
    assert j["after"]["n"] == len(test) == j["n_test"]
    assert j["after"]["rms_mm"] == pytest.approx(float(np.sqrt(np.mean(err ** 2))), rel=1e-5)
    assert j["after"]["mean_mm"] == pytest.approx(float(err.mean()), rel=1e-5)
    assert j["ladder"][-1]["test_rms_mm"] == j["after"]["rms_mm"]
    assert j["ladder"][0]["test_rms_mm"] == j["before"]["rms_mm"] > 5 * j["after"]["rms_mm"]


def test_ladder_steps_and_leave_one_group_out(diag):
    j = diag.to_json()
    names = [s["model"] for s in j["ladder"]]
    assert names == ["located nominal", "+ joint offsets", "+ full geometry", "+ joint_compliance j3"]
    for s in j["ladder"]:
        assert set(s) >= {"model", "added", "n_params", "test_mean_mm", "test_rms_mm", "test_max_mm", "p_value"}
        assert s["test_max_mm"] >= s["test_rms_mm"] >= s["test_mean_mm"] > 0
    assert [s["n_params"] for s in j["ladder"]] == sorted(s["n_params"] for s in j["ladder"])
    assert all(s["p_value"] < 1e-3 for s in j["ladder"][1:])
    logo = {g["without"]: g for g in j["leave_one_group_out"]}
    assert set(logo) == {"joint offsets", "the rest of the geometry", "joint_compliance j3"}
    assert logo["joint_compliance j3"]["loss_rms_mm"] > 0.05
    assert logo["the rest of the geometry"]["loss_rms_mm"] > logo["joint_compliance j3"]["loss_rms_mm"]
    u = j["uncertainty"]
    assert 0.4 < u["median_abs_z"] < 1.0 and u["within_2sigma"] > 0.85


def test_ladder_lines_wrap_long_labels_at_words_and_keep_the_columns():
    """A step named by a long effect label (TIAGo: 'backlash_gravity arm_6_joint (preload 0.145 N m, tool mass 0
    kg)') wraps at its words below the numbers: nothing cut mid-word, every number in its column."""
    from calib.diagnose.ladder import Ladder, Scored

    long = "+ backlash_gravity joint 6 (preload 0.145 N m, tool mass 0 kg) and a second long clause"

    def step(name, k, err):
        return Scored(name, name, None, [f"p{i}" for i in range(k)], np.full((4, 3), err), 1.0, 12)

    steps = [step("located nominal", 18, 3.0), step(long, 43, 1.0)]
    lad = Ladder(steps, [(step("without " + long, 42, 2.0), steps[-1])], "k-fold", p_values=[(None, None),
                                                                                           (5.0, 1e-9)])
    lines = lad.lines()
    words = " ".join(" ".join(ln.split()) for ln in lines)
    for w in long.split():
        assert w in words.split(), w                          # every word whole
    head = lines[0]
    rows = [ln for ln in lines[1:3 + 1] if ln.rstrip().endswith(("-", "1e-09"))]
    assert len(rows) == 2
    for ln in rows:                                           # the RMS column ends where its header ends
        col_end = head.index("RMS") + len("RMS")
        assert ln[col_end - 6:col_end].strip().replace(".", "").isdigit(), (head, ln)
    assert all(len(ln) <= 110 for ln in lines)
