"""Benchmark: robocal's geometric identification against pybotics', geometric against geometric, on data robocal did
not generate.

Data: an independent generator, the tests' oracle (tests/fakes/oracle/chain.py: plain numpy 4x4 products of the
thesis's link matrix ``A_j Ry(beta_j)``, ``A_j = Rz(q_j + theta_j) Tz(d_j) Tx(a_j) Rx(alpha_j)``, a base pose and a
tool point), for a Puma 560 whose geometry is the description's plus random errors (a, d: 0.5 mm; alpha, theta: 0.1
degree; base and tool away from nominal), random poses inside the joint limits, isotropic measurement noise on every
point.  Two data sets:

* ``hayati-free``: axes 2 and 3 exactly parallel in the truth (beta = 0): both models can represent the truth;
* ``hayati``: a Hayati tilt beta_2 (0.1 degree) between the parallel axes 2-3: robocal's model has it, pybotics'
  modified DH has no beta (its d parameters must stand in for it).

Fits, same training poses, same start:

* robocal geometric: ``calib.identify.identify`` on the geometric ``MeasurementModel`` (base, DH with beta for the
  parallel pair, tool point; identifiability guard, robust pass, analytic Jacobian);
* pybotics 3.1 geometric: its MDH model of the same chain, its ``optimize_accuracy`` per-pose distance residuals
  under ``scipy.optimize.least_squares`` (defaults, finite-difference Jacobian), world frame, tool position and the
  MDH parameters a pybotics user would free (link 1 left to the world frame, the parallel pair's d_2 and the last
  joint's theta/d left to the tool, as robocal does); started from robocal's start converted exactly: the rigid base
  fit plus Chapter 6's linear solve of the translations (the start is checked to predict the same points in both).

Prints both fits' time (median and spread over interleaved repeats), pybotics' stop status (converged or stopped,
iterations, why), held-out RMS and max distance to the true points; and, on a separate line not comparable with the
two above, robocal's full model (geometry + the thesis's running effects, about 49 parameters estimated) on the same
data (whose truth has no running effects).

pybotics is optional (pins numpy < 2, though 3.1.2 runs on numpy 2): ``pip install --no-deps pybotics==3.1.2 attrs``.

With its defaults pybotics stops on scipy's step test (``xtol`` is relative to |x|, and the base position is about
1,800 mm) while the gradient is still large; ``--pybotics-x-scale-jac`` lets it run to the optimum (slowly).

    python benchmarks/bench_identify_vs_pybotics.py [--poses 500 --holdout 200 --repeats 3 --noise-mm 0.05]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from dataclasses import dataclass

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import numpy as np  # noqa: E402

from calib.effects import PoseContext, effect_from_text  # noqa: E402
from calib.identify import PointObservations, identify, initial_base, linear_translations  # noqa: E402
from calib.model import MeasurementModel  # noqa: E402
from calib.robot import load_robot  # noqa: E402
from tests.fakes.oracle.chain import base_matrix, dh_frames, point_in, rot_x, trans  # noqa: E402

EFFECTS = ("transmission_error:2:1.0:2", "transmission_error:3:1.0:2", "transmission_error:4:0.9:2",
           "transmission_error:6:1.8:2", "joint_compliance:2", "joint_compliance:3", "joint_compliance:4",
           "cross_coupling:6:5", "cross_coupling:5:4", "cross_coupling:6:4")
INSTALL = "pip install --no-deps pybotics==3.1.2 attrs"
DEG = np.pi / 180.0


# -- the independent generator: the tests' oracle chain (tests/fakes/oracle/chain.py) --------------------------------
@dataclass
class Geometry:
    """A serial chain in the thesis's convention, with the base pose and the tool point: the truth of a data set."""

    a: np.ndarray
    d: np.ndarray
    alpha: np.ndarray
    theta: np.ndarray
    beta: np.ndarray
    base_xyz: np.ndarray
    base_zyx: np.ndarray          # yaw, pitch, roll
    tool: np.ndarray

    def points(self, q: np.ndarray) -> np.ndarray:
        T = dh_frames(base_matrix(self.base_xyz, *self.base_zyx), q + self.theta, self.d, self.a, self.alpha,
                      self.beta)[-1]
        return point_in(T, self.tool)


def true_geometry(robot, rng, hayati: bool) -> Geometry:
    n = robot.n
    g = Geometry(robot.a_mm + rng.normal(0, 0.5, n), robot.d_mm + rng.normal(0, 0.5, n),
                 robot.alpha_rad + rng.normal(0, 0.1 * DEG, n), robot.theta_offset_rad + rng.normal(0, 0.1 * DEG, n),
                 np.zeros(n), np.array([1800.0, -400.0, 250.0]), np.array([35 * DEG, 0.4 * DEG, -0.3 * DEG]),
                 np.array([6.0, -4.0, 95.0]))
    if hayati:
        j = int(np.flatnonzero(robot.hayati)[0])
        g.beta[j] = 0.1 * DEG
    return g


def random_poses(robot, rng, n: int) -> np.ndarray:
    lo, hi = robot.limits_rad[:, 0], robot.limits_rad[:, 1]
    return lo + (hi - lo) * rng.random((n, robot.n))


# -- pybotics ----------------------------------------------------------------------------------------------------------
def pybotics_start(robot, th: np.ndarray, names: list[str]):
    """pybotics Robot equal to robocal's parameter vector ``th`` (beta must be zero: MDH has none)."""
    from pybotics.robot import Robot as PRobot

    v = dict(zip(names, th))
    n = robot.n
    assert all(abs(v[f"j{j + 1}.beta_rad"]) < 1e-12 for j in range(n)), "MDH cannot hold a Hayati beta"
    rows = [[v[f"j{j}.alpha_rad"] if j else 0.0, v[f"j{j}.a_mm"] if j else 0.0,
             v[f"j{j + 1}.theta_offset_rad"], v[f"j{j + 1}.d_mm"]] for j in range(n)]
    pr = PRobot.from_parameters(np.array(rows))
    pr.tool.matrix = (trans(v[f"j{n}.a_mm"], 0, 0) @ rot_x(v[f"j{n}.alpha_rad"])
                      @ trans(v["tool.x_mm"], v["tool.y_mm"], v["tool.z_mm"]))
    pr.world_frame = base_matrix([v["base.x_mm"], v["base.y_mm"], v["base.z_mm"]], v["base.yaw_rad"],
                                 v["base.pitch_rad"], v["base.roll_rad"])
    return pr


def pybotics_mask(n: int) -> list[bool]:
    """MDH [alpha_{i-1}, a_{i-1}, theta_i, d_i] per link: link 1 is the world frame's, d_2 (parallel pair) and the
    last link's theta and d are the tool position's."""
    mask = [[False] * 4] + [[True] * 4 for _ in range(n - 1)]
    mask[1][3] = False
    mask[-1][2] = mask[-1][3] = False
    return [b for row in mask for b in row]


#: scipy.optimize.least_squares status -> what it means for the fit
STOP = {0: "stopped early: evaluation limit reached", 1: "converged: gradient below gtol",
        2: "stopped: cost change below ftol (not a gradient test)", 3: "stopped: step below xtol (not a gradient test)",
        4: "stopped: cost change and step below tolerance (not a gradient test)"}


@dataclass
class PyboticsFit:
    seconds: float
    pred: np.ndarray
    n_params: int
    status: str
    converged: bool          # scipy's gradient test passed (status 1); otherwise a time ratio compares unlike fits


def pybotics_fit(pr, q_train, p_train, q_test, x_scale: str | float = 1.0) -> PyboticsFit:
    from scipy.optimize import least_squares

    from pybotics.optimization import OptimizationHandler, optimize_accuracy

    handler = OptimizationHandler(robot=pr, kinematic_chain_mask=pybotics_mask(len(pr)),
                                  tool_mask=[True, True, True, False, False, False], world_mask=[True] * 6)
    x0 = handler.generate_optimization_vector()
    t0 = time.perf_counter()
    res = least_squares(optimize_accuracy, x0, args=(handler, q_train, p_train), x_scale=x_scale)
    handler.apply_optimization_vector(res.x)
    seconds = time.perf_counter() - t0
    status = (f"{STOP.get(res.status, 'failed')} (scipy status {res.status}: {res.message}); {res.nfev} evaluations, "
              f"{res.njev} Jacobians (finite differences), first-order optimality {res.optimality:.2g} at the end")
    pred = np.array([handler.robot.fk(qi)[:3, 3] for qi in q_test])
    return PyboticsFit(seconds, pred, x0.size, status, res.status == 1)


# -- one data set --------------------------------------------------------------------------------------------------
@dataclass
class DataSet:
    name: str
    truth: Geometry
    obs: PointObservations
    q_hold: np.ndarray
    p_hold: np.ndarray            # true (noise-free) held-out points


def make_data(robot, name: str, seed: int, n: int, n_hold: int, noise_mm: float) -> DataSet:
    rng = np.random.default_rng(seed)
    g = true_geometry(robot, rng, hayati=name == "hayati")
    q, q_h = random_poses(robot, rng, n), random_poses(robot, rng, n_hold)
    p = g.points(q) + rng.normal(0, noise_mm, (n, 3))
    ctx = PoseContext(n, robot.n, payload_kg=np.where(np.arange(n) % 2 == 0, 0.0, 5.0))
    return DataSet(name, g, PointObservations(q, p, sigma_mm=noise_mm, ctx=ctx), q_h, g.points(q_h))


def errors(pred: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    e = np.linalg.norm(pred - truth, axis=1)
    return float(np.sqrt(np.mean(e ** 2))), float(e.max())


def robocal_fit(model: MeasurementModel, ds: DataSet):
    t0 = time.perf_counter()
    res = identify(model, ds.obs)
    seconds = time.perf_counter() - t0
    ctx_h = PoseContext(len(ds.q_hold), model.robot.n)
    return seconds, res, model.points(ds.q_hold, ctx_h, res.theta[: model.P])


def robocal_start(geo: MeasurementModel, ds: DataSet, free: list[str]) -> np.ndarray:
    """robocal's start: rigid base fit, then Chapter 6's linear solve of the translations it estimates."""
    th = initial_base(geo, ds.obs.q_rad, ds.obs.points_mm, ds.obs.ctx)
    lengths = [n for n in free if n.endswith("_mm") and n in geo.kin.index]
    return linear_translations(geo, ds.obs, th, lengths)


def spread(ts: list[float]) -> str:
    return f"{statistics.median(ts):7.2f} ({min(ts):.2f}-{max(ts):.2f})"


def run_set(ds: DataSet, robot, repeats: int, have_pybotics: bool, x_scale: str | float) -> None:
    geo, full = MeasurementModel(robot), MeasurementModel(robot, [effect_from_text(s) for s in EFFECTS])
    t_geo, t_full, t_pb = [], [], []
    for _ in range(repeats):                                          # interleaved: load drifts hit all alike
        s, res_g, pred_g = robocal_fit(geo, ds)
        t_geo.append(s)
        if have_pybotics:
            th0 = robocal_start(geo, ds, res_g.free)
            pr = pybotics_start(robot, th0, geo.names)
            p0 = np.array([pr.fk(qi)[:3, 3] for qi in ds.obs.q_rad[:50]])
            gap = float(np.abs(p0 - geo.points(ds.obs.q_rad[:50], None, th0)).max())
            assert gap < 1e-6, f"pybotics start differs from robocal's by {gap:g} mm"
            start_rms = errors(geo.points(ds.q_hold, None, th0), ds.p_hold)[0]
            fit = pybotics_fit(pr, ds.obs.q_rad, ds.obs.points_mm, ds.q_hold, x_scale)
            t_pb.append(fit.seconds)
        s, res_f, pred_f = robocal_fit(full, ds)
        t_full.append(s)
    print(f"\n data set {ds.name!r}: {ds.obs.n} training poses (noise {ds.obs.sigma_mm:g} mm per coordinate), "
          f"{len(ds.q_hold)} held out; truth beta_2 = {np.degrees(ds.truth.beta.max()):.2f} deg")
    print(f"  {'fit':<44}{'params':>7}{'time s median (min-max)':>26}{'RMS mm':>9}{'max mm':>9}")
    rms, mx = errors(pred_g, ds.p_hold)
    print(f"  {'robocal geometric':<44}{len(res_g.free):>7d}{spread(t_geo):>26}{rms:>9.4f}{mx:>9.4f}")
    if have_pybotics:
        rms_p, mx_p = errors(fit.pred, ds.p_hold)
        label = "pybotics 3.1 geometric (MDH, same start)" + (", x_scale=jac" if x_scale == "jac" else "")
        print(f"  {label:<44}{fit.n_params:>7d}{spread(t_pb):>26}"
              f"{rms_p:>9.4f}{mx_p:>9.4f}")
        print(f"    pybotics stop: {fit.status}")
        ratio = statistics.median(t_pb) / statistics.median(t_geo)
        verdict = (f"robocal is {ratio:.1f}x faster (medians, both converged)" if fit.converged else
                   f"time ratio {ratio:.1f}x (medians) is not a speed-up: pybotics stopped before converging")
        print(f"    common start (base fit + linear translations): held-out RMS {start_rms:.3f} mm; {verdict}")
    else:
        print(f"  pybotics: not installed ({INSTALL}): comparison skipped")
    rms, mx = errors(pred_f, ds.p_hold)
    print(f"  separate line, not like for like -- robocal full model (geometry + thesis effects, {len(full.names)} "
          f"parameters, {len(res_f.free)} estimated): {spread(t_full).strip()} s, held-out RMS {rms:.4f} mm, "
          f"max {mx:.4f} mm")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=500)
    ap.add_argument("--holdout", type=int, default=200)
    ap.add_argument("--noise-mm", type=float, default=0.05)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--sets", default="hayati-free,hayati")
    ap.add_argument("--pybotics-x-scale-jac", action="store_true",
                    help="run pybotics' least_squares with x_scale='jac' (not its default): it then converges, slowly "
                         "(about 7 minutes for 500 poses on the 2-core machine)")
    a = ap.parse_args(argv)
    try:
        import pybotics  # noqa: F401
        have = True
    except ImportError:
        have = False
    robot = load_robot()
    warm = make_data(robot, "hayati-free", a.seed, 60, 10, a.noise_mm)
    for model in (MeasurementModel(robot), MeasurementModel(robot, [effect_from_text(s) for s in EFFECTS])):
        robocal_fit(model, warm)                                      # first-call costs (imports, caches): untimed
    print(f"identification on independently generated data, {a.repeats} interleaved repeats, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    for k, name in enumerate(a.sets.split(",")):
        run_set(make_data(robot, name, a.seed + k, a.poses, a.holdout, a.noise_mm), robot, a.repeats, have,
                "jac" if a.pybotics_x_scale_jac else 1.0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
