"""Benchmark: how identification and diagnosis time grow with the number of poses (issue 18, item 7).

Data: the Puma 560 twin (default scenario: the thesis's geometry errors, transmission errors on joints 4 and 6,
two-slope compliance on joints 3 and 4), measured by its two simulated theodolites (points by intersection, with
their covariance), every other pose with a 5 kg payload so that the compliances are driven.  In-process timings
(imports, a warm-up fit and data generation not counted), one BLAS thread, best of ``--repeat`` (of at least 3
below 1000 poses):

* identification, geometric model (39 parameters before the identifiability guard);
* identification with the thesis's running errors (``robocal identify --thesis-effects``: transmission errors 4 and 6,
  compliances 3 and 4, coupling 6 <- 5);
* diagnosis (``robocal diagnose``'s engine, level auto) of the same data.

``--torque-term`` instead measures when the torque-derivative term of the Jacobian matters
(:func:`calib.model.torque_term_matters`): the same thesis-effects identification with the term forced on and
forced off, on the default scenario and on ones whose joints are ``--soft`` times more compliant, printing the
term's size bound eps, the time, the largest change of a converged parameter in sigmas, of a sigma, and the held-out
RMS of both.

Run: ``PYTHONPATH=. python benchmarks/bench_scaling.py [--poses 100 300 1000 3000] [--diagnose 100 300 1000 3000]``
or ``PYTHONPATH=. python benchmarks/bench_scaling.py --torque-term [--poses 1000]``.
"""
from __future__ import annotations

import argparse
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = "1"

import copy  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

import calib.model as model_mod  # noqa: E402
from calib.effects import THESIS_RUNNING_ERRORS, JointCompliance, effect_from_text  # noqa: E402
from calib.identify import PointObservations, identify  # noqa: E402
from calib.model import MeasurementModel  # noqa: E402
from calib.theodolite import intersect  # noqa: E402
from sim.twin import Twin, load_scenario  # noqa: E402


def measure(tw: Twin, n: int):
    """n random poses of the twin, every other one with a 5 kg payload, points intersected from the readings."""
    q = tw.random_poses(n)
    ctx = tw.context(n, payload_kg=np.where(np.arange(n) % 2 == 0, 0.0, 5.0))
    m = tw.measure(q, ctx)
    k = len(tw.stations)
    pts = intersect(tw.stations, [(m.readings_rad[:, 2 * i], m.readings_rad[:, 2 * i + 1]) for i in range(k)])
    obs_ctx = MeasurementModel(tw.robot).context(n, payload_kg=ctx.payload_kg)
    return PointObservations(m.q_read_rad, pts.point_mm, pts.cov_mm2, ctx=obs_ctx), m.point_true_mm


def thesis_model(robot) -> MeasurementModel:
    return MeasurementModel(robot, [effect_from_text(s, robot.n) for s in THESIS_RUNNING_ERRORS])


def best_of(fn, repeat: int):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def machine() -> str:
    load = os.getloadavg()
    return (f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy "
            f"{np.__version__}; load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min)")


def scaling(args) -> None:
    from calib.diagnose.data import from_arrays
    from calib.diagnose.engine import diagnose

    tw = Twin(seed=args.seed)
    print(f"robocal benchmark: scaling with the pose count, Puma 560 twin (default scenario), one BLAS thread, "
          f"best of {args.repeat} (of at least 3 below 1000 poses); {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"  machine: {machine()}")
    warm, _ = measure(tw, 60)                   # first calls import and build what later calls reuse: untimed
    identify(thesis_model(tw.robot), warm)
    print(f"  {'poses':>6} {'identify geometric s':>21} {'identify thesis effects s':>26} {'diagnose s':>11}")
    for n in sorted(set(args.poses) | set(args.diagnose)):
        obs, _ = measure(tw, n)
        cells = []
        if n in args.poses:
            repeat = args.repeat if n >= 1000 else max(3, args.repeat)       # small cases: best of 3 at least
            t_geo, _ = best_of(lambda: identify(MeasurementModel(tw.robot), obs), repeat)
            t_eff, _ = best_of(lambda: identify(thesis_model(tw.robot), obs), repeat)
            cells += [f"{t_geo:21.2f}", f"{t_eff:26.2f}"]
        else:
            cells += [f"{'-':>21}", f"{'-':>26}"]
        if n in args.diagnose:
            data = from_arrays(tw.robot, obs.q_rad, obs.points_mm, obs.cov_mm2, payload_kg=obs.ctx.payload_kg)
            t_diag, _ = best_of(lambda: diagnose(data), 1)
            cells.append(f"{t_diag:11.2f}")
        else:
            cells.append(f"{'-':>11}")
        print(f"  {n:>6} " + " ".join(cells), flush=True)


def softened(scale: float) -> Twin:
    """The default twin with every joint compliance ``scale`` times larger (stiffnesses divided by it)."""
    sc = copy.deepcopy(load_scenario())
    for e in sc.effects:
        if isinstance(e, JointCompliance):
            e.values[:2] *= scale
            e.values[2] /= scale          # the same deflection at the slope change
    return Twin(sc)


def torque_term(args) -> None:
    n = max(args.poses)
    print(f"robocal benchmark: does the torque-derivative term of the Jacobian change the identification? "
          f"{n} poses + {args.holdout} held out, thesis effects, one BLAS thread; "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"  machine: {machine()}")
    print(f"  {'scenario':<28} {'eps':>7} {'term':>5} {'time s':>7} {'max |d theta|/sigma':>20} "
          f"{'max |d sigma|/sigma':>20} {'held-out RMS mm':>16}")
    warm_twin = Twin(seed=args.seed)
    warm, _ = measure(warm_twin, 60)                   # first calls import and build: untimed
    identify(thesis_model(warm_twin.robot), warm)
    cases = [("default (thesis compliances)", lambda: Twin(seed=args.seed))]
    cases += [(f"{k:g}x more compliant", lambda k=k: softened(k)) for k in args.soft]
    for label, make in cases:
        tw = make()
        tw.rng = np.random.default_rng(args.seed)
        obs, _ = measure(tw, n)
        obs_h, truth_h = measure(tw, args.holdout)
        res = {}
        threshold = model_mod.TORQUE_TERM_THRESHOLD
        for term in (True, False):
            model_mod.TORQUE_TERM_THRESHOLD = 0.0 if term else np.inf
            model = thesis_model(tw.robot)
            t, r = best_of(lambda: identify(model, obs), 1)
            pred = model.points(obs_h.q_rad, obs_h.ctx, r.theta[: model.P])
            rms = float(np.sqrt(np.mean(np.sum((pred - truth_h) ** 2, axis=1))))
            res[term] = (t, r, rms, model)
        model_mod.TORQUE_TERM_THRESHOLD = threshold
        on, off = res[True][1], res[False][1]
        model = res[True][3]
        ev = model.evaluate(obs.q_rad, obs.ctx, on.theta[: model.P])
        eps = model_mod.torque_term_size(model.torque_gain(ev), ev.loads)
        idx = [on.names.index(k) for k in on.free if k in off.free]
        s_on, s_off = on.sigma[idx], off.sigma[idx]
        dth = np.max(np.abs(on.theta[idx] - off.theta[idx]) / s_on)
        dsig = np.max(np.abs(s_off / s_on - 1.0))
        for term in (True, False):
            t, _, rms, _ = res[term]
            extra = f"{dth:20.3f} {dsig:20.4f}" if not term else f"{'(reference)':>20} {'':>20}"
            eps_txt = f"{eps:7.4f}" if term else f"{'':7}"
            print(f"  {label if term else '':<28} {eps_txt} {'on' if term else 'off':>5} "
                  f"{t:7.2f} {extra} {rms:16.4f}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, nargs="+", default=[100, 300, 1000, 3000])
    ap.add_argument("--diagnose", type=int, nargs="*", default=[100, 300, 1000, 3000])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--torque-term", action="store_true", help="measure when the torque term matters instead")
    ap.add_argument("--soft", type=float, nargs="+", default=[10.0, 30.0],
                    help="compliance factors of the soft scenarios")
    ap.add_argument("--holdout", type=int, default=300)
    args = ap.parse_args()
    (torque_term if args.torque_term else scaling)(args)


if __name__ == "__main__":
    main()
