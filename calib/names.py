"""The one place names are made for people: joints by their description's names, parameters with their edge units.

Inside, a joint is an index and a parameter has a code name in internal units (``j7.theta_offset_rad``,
``joint_compliance.j3.compliance_rad_per_nm``).  What a person reads -- terminal, report, plots, identifiability
sentences, diagnosis findings, the side file -- says the joint as its description names it (``arm_6_joint``) and
angles in degrees (``arm_6_joint.theta_offset_deg``); what a person types (``--free``, ``--prior``, ``--effect``,
``[tolerances]``) may use either form and is mapped back here.  Every output site calls this module instead of
formatting names itself, so the display form cannot drift between outputs.

Display joint names: the description's own (a URDF's joint names; a DH description's ``name = ...``) when every one is
a single word (``[A-Za-z_][A-Za-z0-9_-]*``, so that it can be typed in a pattern and read in a parameter name);
otherwise ``j1`` .. ``jn`` (the thesis's Puma names its joints "wrist roll", "wrist bend").
"""
from __future__ import annotations

import re

from .errors import RobocalError
from .units import DEG

_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_\-]*\Z")
_JOINT_TOKEN = re.compile(r"j(\d+)((?:@\d+)?)\Z")
#: internal unit suffix -> unit, longest first (``_rad_per_nm`` before ``_rad``)
_UNITS = (("_rad_per_nm", "rad/(N m)"), ("_per_nmm2", "1/(N mm^2)"), ("_per_degc", "1/degC"), ("_kgmm", "kg mm"),
          ("_kg", "kg"), ("_mm", "mm"), ("_rad", "rad"), ("_nm", "N m"))
#: internal unit -> (edge unit, internal units per edge unit); the rest are shown as they are
_EDGE = {"rad": ("deg", DEG)}


# -- joints ---------------------------------------------------------------------------------------------------------
def joint_names(robot) -> tuple[str, ...]:
    """The names a person reads for the robot's joints (see the module docstring)."""
    names = tuple(getattr(robot, "joint_names", ()) or ())
    n = robot.n
    if len(names) == n and all(_WORD.match(s) for s in names) and len(set(names)) == n:
        return names
    return tuple(f"j{k}" for k in range(1, n + 1))


def joint_name(robot, j: int) -> str:
    """Joint ``j`` (1-based) as a person reads it."""
    return joint_names(robot)[j - 1]


def joint_number(robot, text: str) -> int | None:
    """The 1-based joint a person named: ``3``, ``j3``, ``q3`` or the joint's name; None when it names none."""
    text = str(text).strip()
    names = joint_names(robot)
    if text in names:
        return names.index(text) + 1
    own = tuple(getattr(robot, "joint_names", ()) or ())
    if text in own:
        return own.index(text) + 1
    m = re.fullmatch(r"[jqJQ]?(\d+)", text)
    if m and 1 <= int(m.group(1)) <= robot.n:
        return int(m.group(1))
    return None


def is_prismatic(robot, j: int) -> bool:
    pris = getattr(robot, "prismatic", None)
    return bool(pris is not None and len(pris) >= j and pris[j - 1])


def joint_value_unit(robot, j: int) -> str:
    """The edge unit of joint ``j``'s value: mm for a prismatic joint, deg otherwise."""
    return "mm" if is_prismatic(robot, j) else "deg"


def zero_offset_parameter(robot, j: int) -> str:
    """The code name of joint ``j``'s zero offset: what its reading adds to (d for a prismatic joint, in mm)."""
    return f"j{j}.d_mm" if is_prismatic(robot, j) else f"j{j}.theta_offset_rad"


# -- parameters -----------------------------------------------------------------------------------------------------
def unit_of(name: str) -> str:
    """The internal unit a parameter's name carries (``1`` for a pure number)."""
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return unit
    return "1"


def edge_unit(unit: str) -> tuple[str, float]:
    """(edge unit, internal units per edge unit) of an internal unit: rad is shown in degrees."""
    return _EDGE.get(unit, (unit, 1.0))


def quantity_words(key: str) -> tuple[str, str]:
    """(words, unit) of an edge-unit parameter key as a JSON entry holds it: ``width_deg`` -> ("width", "deg"),
    ``preload_nm`` -> ("preload", "N m"), ``tool_mass_kg`` -> ("tool mass", "kg"); a pure number has unit ""."""
    for suffix, unit in (("_deg", "deg"),) + _UNITS:
        if key.endswith(suffix) and len(key) > len(suffix):
            return key[: -len(suffix)].replace("_", " "), unit
    return key.replace("_", " "), ""


def _tokens(name: str) -> list[str]:
    return name.split(".")


def joint_of(name: str, n: int) -> int | None:
    """The 1-based joint a code name is about (``j3.a_mm``, ``joint_compliance.j3.k``), None for base, tool, ..."""
    for tok in _tokens(name):
        m = _JOINT_TOKEN.match(tok)
        if m and 1 <= int(m.group(1)) <= n:
            return int(m.group(1))
    return None


def display(name: str, robot) -> str:
    """A code name with its joints named: ``j7.a_mm`` -> ``arm_6_joint.a_mm``, ``joint_compliance.j3.k`` ->
    ``joint_compliance.arm_2_joint.k`` (units unchanged)."""
    if robot is None:
        return name
    names = joint_names(robot)
    out = []
    for tok in _tokens(name):
        m = _JOINT_TOKEN.match(tok)
        if m and 1 <= int(m.group(1)) <= len(names):
            tok = names[int(m.group(1)) - 1] + m.group(2)
        out.append(tok)
    return ".".join(out)


def edge_name(name: str, robot=None) -> str:
    """The name a person reads, in the unit shown: joints named, ``_rad`` as ``_deg``."""
    shown = display(name, robot)
    return shown[: -len("_rad")] + "_deg" if shown.endswith("_rad") else shown


def edge(name: str, value: float, sigma: float | None, robot=None) -> tuple[str, float, float | None, str]:
    """(shown name, value, sigma, unit) in edge units: what a table row or a JSON entry for people holds."""
    unit, scale = edge_unit(unit_of(name))
    return (edge_name(name, robot), value / scale, None if sigma is None else sigma / scale, unit)


def internal(text: str, robot, known) -> tuple[str, float]:
    """(code name, internal units per given unit) for a name a person typed in any form :func:`edge` or
    :func:`display` prints, or the code name itself; one line naming the choices when it is none of them."""
    for cand, scale in _candidates(text.strip(), robot):
        if cand in known:
            return cand, scale
    names = joint_names(robot) if robot is not None else ()
    example = f", {names[0]}.a_mm, {names[0]}.alpha_deg" if names else ""
    raise RobocalError(f"{text!r} is not a parameter of the model (e.g. {', '.join(list(known)[:3])}{example})")


def _candidates(text: str, robot):
    code = ".".join(_code_token(tok, robot) for tok in _tokens(text))
    yield code, 1.0
    if code.endswith("_deg"):
        yield code[: -len("_deg")] + "_rad", DEG


def _code_token(tok: str, robot) -> str:
    if robot is None:
        return tok
    base, at, rest = tok.partition("@")
    j = _named_joint(robot, base)
    return f"j{j}{at}{rest}" if j else tok


def _named_joint(robot, text: str) -> int | None:
    names = joint_names(robot)
    if text in names:
        return names.index(text) + 1
    own = tuple(getattr(robot, "joint_names", ()) or ())
    return own.index(text) + 1 if text in own else None


def shown_forms(name: str, robot) -> tuple[str, ...]:
    """Every form of a code name a person may have read or typed (for matching ``--free`` patterns)."""
    forms = dict.fromkeys((name, display(name, robot), edge_name(name, robot), edge_name(name)))
    own = tuple(getattr(robot, "joint_names", ()) or ()) if robot is not None else ()
    if own and own != joint_names(robot):                # a description name that is not shown (has a space)
        head, _, tail = name.partition(".")
        m = _JOINT_TOKEN.match(head)
        if m and 1 <= int(m.group(1)) <= len(own):
            forms[f"{own[int(m.group(1)) - 1]}.{tail}"] = None
    return tuple(forms)


_TEXT_JOINT = re.compile(r"(?<![\w.])[jq](\d+)(?![\w])")
_TEXT_PHRASE = re.compile(r"\b([Jj])oint (\d+)\b(?!\.\d)")
_TEXT_PLURAL = re.compile(r"\b([Jj])oints (\d+(?:(?:, | and )\d+)*)\b")


def named(robot) -> bool:
    """True when the robot's joints are shown by their description's names (see the module docstring)."""
    return robot is not None and joint_names(robot) != tuple(f"j{k}" for k in range(1, robot.n + 1))


def joint_label(robot, j: int, capital: bool = False) -> str:
    """Joint ``j`` (1-based) in a sentence: its name, or ``joint 3`` for a robot whose joints have none."""
    if named(robot):
        return joint_name(robot, j)
    return f"{'J' if capital else 'j'}oint {j}"


def reading_label(robot, i: int) -> str:
    """Controller reading ``i`` (1-based) in a sentence: its name (a URDF's joint, a reading convention's reading)
    for a robot whose joints have names, else ``joint 3``."""
    rn = tuple(getattr(robot, "reading_names", ()) or ())
    if named(robot) and len(rn) >= i and _WORD.match(rn[i - 1]):
        return rn[i - 1]
    return f"joint {i}"


def prose(text: str, robot) -> str:
    """Text written with joint numbers (``joint 7``, ``joints 1 and 2``, ``j7``, ``q7``, parameter names such as
    ``j7.a_mm``) with the joints named, for a robot whose joints have names; unchanged otherwise.  The output
    boundary of producers whose labels are also keys (the diagnosis's candidates): they keep numbers inside."""
    if not named(robot):
        return text
    names = joint_names(robot)

    def one(k: str, whole: str) -> str:
        return names[int(k) - 1] if 1 <= int(k) <= len(names) else whole

    text = _TEXT_PLURAL.sub(lambda m: m.group(0)[:len("joints ")]
                            + re.sub(r"\d+", lambda d: one(d.group(0), d.group(0)), m.group(2)), text)
    text = _TEXT_PHRASE.sub(lambda m: one(m.group(2), m.group(0)), text)
    return in_text(text, robot)


def with_joint_names(doc, robot):
    """A JSON document with ``<key>_name`` beside every integer ``joint`` / ``source_joint`` (1-based) key: the
    index stays, the name is added."""
    if isinstance(doc, list):
        return [with_joint_names(v, robot) for v in doc]
    if not isinstance(doc, dict):
        return doc
    out = {}
    for k, v in doc.items():
        out[k] = with_joint_names(v, robot)
        if k in ("joint", "source_joint") and isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= robot.n:
            out[f"{k}_name"] = joint_name(robot, v)
    return out


def in_text(text: str, robot) -> str:
    """A label written with ``jK`` joint tokens (an effect's finding label: ``cross_coupling j4->j6``) with the
    joints named."""
    if robot is None:
        return text
    if not named(robot):
        return text
    names = joint_names(robot)
    return _TEXT_JOINT.sub(lambda m: names[int(m.group(1)) - 1] if 1 <= int(m.group(1)) <= len(names)
                           else m.group(0), text)


def effect_label(robot, effect) -> str:
    """An effect as a person reads it: its finding label with the joints named (``joint_compliance arm_2_joint``,
    ``cross_coupling arm_4_joint->arm_6_joint``)."""
    return in_text(effect.finding_label(), robot)
