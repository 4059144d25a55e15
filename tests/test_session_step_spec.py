"""A step's stored record (Step.spec) is dataclasses.asdict of the step, targets and inputs as lists: the same
values, the same types, and a deep copy (changing the record changes no step)."""
from __future__ import annotations

from collections import namedtuple
from dataclasses import asdict

import numpy as np

from acq.session.steps import InputSpec, Step, TargetSpec

Pair = namedtuple("Pair", "a b")


def _asdict_spec(step: Step) -> dict:
    d = asdict(step)
    d["targets"], d["inputs"] = list(d["targets"]), list(d["inputs"])
    return d


def _same(a, b) -> bool:
    """Equal and of the same types all the way down."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return list(a) == list(b) and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return np.array_equal(a, b) and a.dtype == b.dtype
    return a == b


def test_spec_is_asdict_of_the_demo_plans_steps():
    from app.demo import build_demo
    import tempfile
    d = build_demo(tempfile.mktemp(suffix=".db"), seed=0)
    try:
        for s in d.runner.steps:
            assert _same(s.spec(), _asdict_spec(s)), s.key
    finally:
        d.close()


def test_spec_of_odd_values_and_a_deep_copy():
    step = Step("k", "poses", "t", "i", pose_deg=(1.0, 2.0), targets=(TargetSpec("P", tool_mm=(0.0, 0.0, 1.0)),),
                inputs=(InputSpec("load_kg", "kg", "hang it", 2.0, 0.1),),
                setup={"loads": [{"link": 3, "point_mm": [1.0, 2.0, 3.0], "mass_kg": np.float64(2.5)}],
                       "pair": Pair(1, [2, 3]), "nested": TargetSpec("Q", point_mm=(1.0, 2.0, 3.0)), "flag": True,
                       "array": np.arange(3.0)},
                meta={"joint": 3, (1, 2): "tuple key"})
    spec = step.spec()
    assert _same(spec, _asdict_spec(step))
    spec["setup"]["loads"][0]["point_mm"][0] = 99.0
    spec["setup"]["array"][0] = 99.0
    spec["setup"]["pair"].b.append(4)
    assert step.setup["loads"][0]["point_mm"][0] == 1.0 and step.setup["array"][0] == 0.0
    assert step.setup["pair"].b == [2, 3]
