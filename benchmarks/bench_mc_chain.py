"""Monte Carlo draws per second for the whole Chapter 4 chain: ruler -> points -> axes -> DH.

Each draw is a full synthetic session's raw readings (ruler sightings of C, D, E and one sweep per Puma joint, 3"
theodolites, ruler marks to 0.05 mm); one evaluation re-estimates L, gamma1, gamma2, every target position, the six
joint circles and the DH parameters of links 1-5.  The chain is vectorised over draws, so the only Python loops are
the handful of Gauss-Newton iterations of the batched circle fit.

Usage:  python benchmarks/bench_mc_chain.py [--points 8] [--draws 20000] [--chunk 5000]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from calib.estimators import axes, dh, points, ruler
from calib.estimators.chain import synthetic_cpa


def _rate(fn, n, repeat=3):
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return n / best, best


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=8, help="target positions per joint sweep")
    ap.add_argument("--draws", type=int, default=20000, help="Monte Carlo draws for the end-to-end run")
    ap.add_argument("--chunk", type=int, default=5000, help="draws per vectorised batch")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)

    s = synthetic_cpa(seed=a.seed, n_points=a.points)
    c = s.chain
    rng = np.random.default_rng(a.seed)
    X = s.draw(rng, a.chunk)
    print(f"chain: {len(c.n_points)} joints x {a.points} targets, {c.m} raw inputs -> {len(c.names()[0])} DH outputs")

    # stage by stage, one batch of `chunk` draws
    theo = c.theodolite(X)
    N = a.points
    rd = X[:, 8:].reshape(a.chunk, len(c.n_points), N, 3)
    th = np.broadcast_to(theo[:, None, None, :], rd.shape)
    P = points.point_xyz(np.concatenate([rd, th], -1))
    ax = axes.fit_circle(P)
    stages = {
        "ruler (closed form)": lambda: ruler.closed_form(X[:, :8]),
        "points (eq 4.3.1)": lambda: points.point_xyz(np.concatenate([rd, th], -1)),
        "axes (plane + circle)": lambda: axes.fit_circle(P),
        "DH (common normals)": lambda: dh.dh_from_axes(
            ax[..., :3], ax[..., 3:6], c.q_rad, c.frame0_R, c.frame0_t, c.x_hint, c.hayati, c.d_nominal,
            alpha_ref=c.alpha_ref),
        "whole chain": lambda: c(X),
    }
    for name, fn in stages.items():
        rate, dt = _rate(fn, a.chunk)
        print(f"  {name:24s} {rate:12,.0f} draws/s   ({dt * 1e3:8.1f} ms per {a.chunk} draws)")

    # end to end: draws + evaluation + covariance, in chunks
    t = time.perf_counter()
    ys = []
    left = a.draws
    while left > 0:
        n = min(a.chunk, left)
        ys.append(c(s.draw(rng, n)))
        left -= n
    Y = np.concatenate(ys)
    cov = np.cov(Y, rowvar=False)
    dt = time.perf_counter() - t
    mc_rate = a.draws / dt
    print(f"end to end Monte Carlo: {a.draws} draws in {dt:.2f} s = {mc_rate:,.0f} draws/s "
          f"(sampling + chain + covariance)")

    # a Python loop per draw, for comparison
    nloop = 200
    t = time.perf_counter()
    for i in range(nloop):
        c(X[i:i + 1])
    dt = time.perf_counter() - t
    loop_rate = nloop / dt
    print(f"python loop per draw:   {loop_rate:,.0f} draws/s (vectorisation gain x{mc_rate / loop_rate:.0f})")
    sd = np.sqrt(np.diag(cov))
    names = c.names()[0]
    for k in ("j2.a_mm", "j4.d_mm", "j3.a_mm", "j2.beta_rad"):
        i = names.index(k)
        print(f"  MC sigma {k:16s} {sd[i]:.4g}")


if __name__ == "__main__":
    main()
