"""Fuzzing the file readers: ~50,000 inputs across robot and scenario TOML, model and set-up JSON, pose and readings
CSV and the session database (issue 17 item 7; the byte codecs and drivers are ``benchmarks/fuzz.py``).

Targets are defined once in ``tests/fakes/fuzz_file_targets.py`` (the property tests use them at a modest count).
Inputs are byte mutations of valid files (flips, a 4,301-digit integer, ``1e400``, ``nan``, splices, truncation),
value-level damage of the JSON documents and SQL-level damage of the database.  Seeded, so a run is reproducible.
A hang is an input running longer than ``--hang-s``.

Prints per target: inputs, accepted, clean rejections (one ``robocal: error:`` line), crashes, hangs, slowest input;
then the first crashes.  Target: 0 crashes, 0 hangs; exit status 1 otherwise.

    python benchmarks/fuzz_files.py                  # ~50,000 inputs
    python benchmarks/fuzz_files.py --inputs 3000    # a quick look
"""
from __future__ import annotations

import argparse
import collections
import os
import random
import signal
import sys
import time
import traceback
import warnings

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from tests.fakes.fuzz_file_targets import generate_file, targets  # noqa: E402
from tests.fakes.fuzz_targets import outcome  # noqa: E402

#: what issue 17 measured before: 29 % of fuzzed model files crashed `compensate` at 13 code sites
BASELINE = "issue 17 baseline: model JSON 29 % crashes (13 sites); TOML/CSV/JSON/DB readers crashed on encodings, " \
           "huge integers, deep nesting, field limits, damaged databases"


class Hang(Exception):
    pass


def _alarm(signum, frame):
    raise Hang()


def _site(tb: str) -> str:
    """The innermost robocal frame of a traceback (where the crash happened)."""
    frames = [ln.strip() for ln in tb.splitlines() if ln.strip().startswith("File ") and "/calib/" in ln
              or "/acq/" in ln]
    return frames[-1] if frames else "?"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--inputs", type=int, default=50_000, help="total inputs, spread over the targets")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--hang-s", type=float, default=2.0)
    ap.add_argument("--show", type=int, default=5, help="crash inputs to print")
    a = ap.parse_args(argv)
    table = targets()
    per = max(1, a.inputs // len(table))
    signal.signal(signal.SIGALRM, _alarm)
    warnings.simplefilter("ignore")
    rows, crashes, sites = [], [], collections.Counter()
    t_all = time.perf_counter()
    for name, target in table.items():
        rng = random.Random(f"{a.seed}:{name}")
        counts = collections.Counter()
        slowest = 0.0
        for _ in range(per):
            data = generate_file(rng, target)
            t0 = time.perf_counter()
            signal.setitimer(signal.ITIMER_REAL, a.hang_s)
            try:
                counts[outcome(target, data)] += 1
            except Hang:
                counts["hang"] += 1
                crashes.append((name, "hang", data, ""))
            except Exception as exc:  # noqa: BLE001 -- a crash is what we count
                counts["crash"] += 1
                tb = traceback.format_exc()
                sites[(name, type(exc).__name__, _site(tb))] += 1
                crashes.append((name, type(exc).__name__, data, tb))
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            slowest = max(slowest, time.perf_counter() - t0)
        rows.append((name, per, counts["accepted"], counts["rejected"], counts["crash"], counts["hang"], slowest))
    wall = time.perf_counter() - t_all
    print(f"{'reader':20s} {'inputs':>8s} {'accepted':>9s} {'rejected':>9s} {'crashes':>8s} {'hangs':>6s} "
          f"{'slowest_ms':>10s}")
    for name, n, acc, rej, cr, hg, s in rows:
        print(f"{name:20s} {n:8d} {acc:9d} {rej:9d} {cr:8d} {hg:6d} {s * 1000:10.1f}")
    tot = [sum(r[i] for r in rows) for i in range(1, 6)]
    print(f"{'total':20s} {tot[0]:8d} {tot[1]:9d} {tot[2]:9d} {tot[3]:8d} {tot[4]:6d}    ({wall:.0f} s)")
    print(BASELINE)
    if sites:
        print(f"\ncrash sites ({len(sites)}):")
        for (name, exc, site), n in sites.most_common():
            print(f"  {n:6d}  {name}: {exc} at {site}")
    for name, kind, data, tb in crashes[:a.show]:
        print(f"\n{name}: {kind} on {data[:160]!r}\n{tb.rstrip()[-1500:]}")
    ok = tot[3] == 0 and tot[4] == 0
    print(f"result {'PASS' if ok else 'FAIL'} (target: 0 crashes, 0 hangs over {a.hang_s:g} s)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
