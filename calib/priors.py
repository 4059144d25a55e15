"""What an identification may change, and by how much: ``--free PATTERN`` and priors (``--prior``, tolerances).

Weak data (poses spanning a small part of the workspace) determines only part of the chain.  ``--free`` says which
parameters are estimated at all (shell patterns over parameter names); a prior ``NAME=VALUE±SIGMA`` (or a tolerance of
the calibration description: the design value ± its tolerance) adds the pseudo-observation ``(VALUE - p) / SIGMA``, so
a parameter the data cannot see stays at its design value instead of wandering off.

Names: the chain's parameter names (``j3.a_mm``, ``base.z_mm``, ``tool.x_mm``, effect parameters) or, for a
description with joint names, ``JOINT.param`` (``arm_2_joint.a_mm``); angles may be given in degrees by writing the
parameter with ``_deg`` (``j2.alpha_deg=90±0.1``).  Values and sigmas are in the unit the name carries.
"""
from __future__ import annotations

import fnmatch
import re

from . import names as naming
from .errors import RobocalError

_PRIOR = re.compile(r"^\s*([^=\s]+)\s*=\s*([-+0-9.eE]+)\s*(?:±|\+-|\+/-)\s*([0-9.eE+-]+)\s*$")


def canonical(name: str, robot, known) -> tuple[str, float]:
    """(parameter name, scale to internal units) for a user-given name in any form the output prints
    (:func:`calib.names.internal`); RobocalError for an unknown one."""
    return naming.internal(name, robot, known)


def free_from_patterns(model, patterns: list[str]) -> list[str]:
    """Parameters any of whose printed forms (code name, joints named, ``_deg`` for angles: :func:`calib.names.
    shown_forms`) matches any comma-separated shell pattern, in model order."""
    pats = [p.strip() for text in patterns for p in text.split(",") if p.strip()]
    forms = {n: naming.shown_forms(n, model.robot) for n in model.names}

    def hit(n, p):
        return any(fnmatch.fnmatchcase(f, p) for f in forms[n])

    out = [n for n in model.names if any(hit(n, p) for p in pats)]
    if not out:
        raise RobocalError(f"--free {','.join(pats)}: matches no parameter (e.g. 'base.*,tool.*,j*.a_mm')")
    for p in pats:
        if not any(hit(n, p) for n in model.names):
            raise RobocalError(f"--free: pattern {p!r} matches no parameter")
    return out


def parse_prior(text: str, model) -> tuple[str, float, float]:
    m = _PRIOR.match(text)
    if not m:
        raise RobocalError(f"--prior {text!r}: expected NAME=VALUE±SIGMA (or NAME=VALUE+-SIGMA)")
    try:
        name, scale = canonical(m.group(1), model.robot, model.index)
    except RobocalError as exc:
        raise RobocalError(f"--prior {text!r}: {exc}") from None
    value, sigma = float(m.group(2)) * scale, float(m.group(3)) * scale
    if not sigma > 0:
        raise RobocalError(f"--prior {text!r}: SIGMA must be positive")
    return name, value, sigma


def priors_for(model, texts: list[str], free: list[str] | None = None) -> dict[str, tuple[float, float]]:
    """Priors (value, sigma) by parameter: the description's tolerances around the design values, then ``--prior``
    (which wins).  Only parameters that are estimated keep a prior."""
    nominal = model.nominal
    out = {n: (float(nominal[model.index[n]]), sd) for n, sd in model.robot.tolerances.items() if n in model.index}
    for t in texts:
        name, value, sd = parse_prior(t, model)
        out[name] = (value, sd)
    if free is not None:
        out = {n: v for n, v in out.items() if n in free}
    return out
