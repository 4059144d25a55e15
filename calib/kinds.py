"""The one vocabulary of estimates for people: for every kind of parameter, its human name, the unit it is shown in
(with the conversion from the internal unit) and what it means, in one line.

Why one table: the terminal summary, the report's sections, the verdict lines and the verbose table all show the same
estimates; a name or a unit written in each of them drifts (``j6.rad_per_count ... deg``).  Every output asks
:func:`describe` instead.  The code names (``dh.j1.theta_offset_rad``) stay the JSON's keys; people never read them.

A kind is a pattern over code names (a regular expression with the joint numbers as groups ``j`` and ``k``), a name
and a meaning with ``{j}``/``{k}`` for those joints as a person reads them (``joint 4``, or the description's name),
the display unit and the internal units per display unit.  A code name no kind matches is still shown in words: its
tokens spelt out, its joints named, its unit from its suffix (:func:`calib.names.unit_of`, radians in degrees).
Internal units are those of :mod:`calib.units` (mm, rad, N m); angles are shown in degrees, small instrument angles
per count in arc seconds.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache

from .names import edge_unit, unit_of
from .units import ARCSEC, DEG

#: the display unit of a pure number (a ratio, a share): said in words so that no line lacks a unit
DIMENSIONLESS = "dimensionless"
PERCENT = 0.01                      #: a share per percent


@dataclass(frozen=True)
class Kind:
    """One kind of estimate (see the module docstring).  ``magnitude``: its error is judged against its value (a
    length, a stiffness, an amplitude), not against an absolute tolerance (a deviation that may be near zero)."""

    pattern: str
    name: str
    unit: str
    scale: float                    # internal units per display unit
    meaning: str
    magnitude: bool = False


@dataclass(frozen=True)
class Described:
    """A code name as a person reads it: name, display unit, internal units per display unit, meaning."""

    name: str
    unit: str
    scale: float
    meaning: str
    magnitude: bool = False

    @property
    def unit_text(self) -> str:
        """The unit as printed beside a value (``dimensionless`` for a pure number)."""
        return self.unit or DIMENSIONLESS


_J = r"j(?P<j>\d+)"
_K = r"j(?P<k>\d+)"
_DH = {"theta_offset_rad": ("zero offset θ", "deg", DEG, "angle added to the joint's reading (DH θ offset)"),
       "d_mm": ("offset d", "mm", 1.0, "distance along the joint's axis to the next link's common normal (DH d)"),
       "a_mm": ("link length a", "mm", 1.0, "distance along the common normal to the next joint's axis (DH a)"),
       "alpha_rad": ("twist α", "deg", DEG, "angle between the joint's axis and the next one's (DH α)"),
       "beta_rad": ("tilt β", "deg", DEG, "rotation of the next axis about y, for nearly parallel axes (Hayati β)")}
_AXIS = {"dtheta_x_rad": "x", "dtheta_y_rad": "y", "dtheta_z_rad": "z"}
_RELATIVE = {"delta_alpha_rad": ("twist deviation Δα", "the common normal"),
             "delta_beta_rad": ("tilt deviation Δβ", "y of the link frame"),
             "delta_theta_rad": ("turn deviation Δθ", "the joint's own axis")}
_XYZ = ("x", "y", "z")
_RPY = {"yaw_rad": "yaw (about z)", "pitch_rad": "pitch (about y)", "roll_rad": "roll (about x)"}
_COMP = {"a1_mm": ("upper-arm length a1", "eqs 4.3.12-15's a1, from the sweeps' joint centres"),
         "a2_mm": ("forearm offset a2", "eqs 4.3.12-15's a2 (along the base's x)"),
         "d1_mm": ("shoulder offset d1", "eqs 4.3.12-15's d1, between the upper arm and the forearm"),
         "d2_mm": ("elbow-wrist distance d2", "eq 4.3.15's d2: from the elbow axis to the wrist centre"),
         "d3_mm": ("flange distance d3", "eq 4.3.15's d3: from the wrist centre to the flange, from point P")}

KINDS: list[Kind] = [
    # theodolite pre-calibration (section 4.2)
    Kind(r"ruler\.L_mm", "theodolite baseline L", "mm", 1.0,
         "distance between the two theodolites, from the ruler (eq 4.2.1)", magnitude=True),
    Kind(r"ruler\.gamma1_rad", "station A orientation γ1", "deg", DEG,
         "station A's horizontal-circle reading of the baseline A→B (its zero's direction)"),
    Kind(r"ruler\.gamma2_rad", "station B orientation γ2", "deg", DEG,
         "station B's horizontal-circle reading of the baseline B→A (its zero's direction)"),
    Kind(r"ruler\.hB_mm", "station B height hB", "mm", 1.0, "height of theodolite B above theodolite A"),
    # joint axes (section 4.3)
    *[Kind(rf"(?:dh|ident)\.{_J}\.{suffix}", f"{{j}} {name}", unit, scale, meaning)
      for suffix, (name, unit, scale, meaning) in _DH.items()],
    *[Kind(rf"misalign\.{_J}\.{suffix}", f"{{j}} axis misalignment about {axis}", "deg", DEG,
           f"rotation about the compensated frame's {axis} that turns the designed axis into the measured one "
           f"(eq 4.3.10)") for suffix, axis in _AXIS.items()],
    *[Kind(rf"misalign\.{_J}\.{suffix}", f"{{j}} {name}", "deg", DEG,
           f"rotation of the measured axis from the previous joint's, about {about} (eq 4.3.11)")
      for suffix, (name, about) in _RELATIVE.items()],
    *[Kind(rf"comp\.{suffix}", name, "mm", 1.0, meaning) for suffix, (name, meaning) in _COMP.items()],
    # transmission error (section 4.4)
    Kind(rf"te\.{_J}\.omega", "{j} transmission-error frequency", "cycles/rev", 1.0,
         "cycles of the transmission error per revolution of the joint (ω in the error's sin(ω θ))",
         magnitude=True),
    Kind(rf"te\.{_J}\.amplitude1_rad", "{j} transmission-error amplitude", "deg", DEG,
         "amplitude of the first harmonic of the measured angle less the encoder's", magnitude=True),
    Kind(rf"te\.{_J}\.E_a_slope", "{j} commanded-angle scale error", "%", PERCENT,
         "how much more the joint turns than commanded, per cent of the commanded angle (a gear-ratio error)"),
    # joint stiffness (section 4.5)
    Kind(rf"compliance\.{_J}\.K1_Nm_per_rad", "{j} stiffness K", "N m/rad", 1.0,
         "torque per radian of deflection of the joint (below the breakpoint, or one slope over every load)",
         magnitude=True),
    Kind(rf"compliance\.{_J}\.K2_Nm_per_rad", "{j} stiffness above the breakpoint", "N m/rad", 1.0,
         "torque per radian of deflection of the joint above the breakpoint torque", magnitude=True),
    Kind(rf"compliance\.{_J}\.breakpoint_Nm", "{j} stiffness breakpoint", "N m", 1.0,
         "torque at which the joint's stiffness changes", magnitude=True),
    Kind(rf"compliance\.{_J}\.offset_rad", "{j} deflection at no load", "deg", DEG,
         "the fitted line's deflection at zero torque (a set-up offset, not a property of the joint)"),
    # link compliance (section 4.6)
    Kind(rf"link\.{_J}\.EI(?:_lower_bound|_upper_bound)?_Nmm2", "{j} link's flexural rigidity EI", "N mm²", 1.0,
         "bending stiffness of the link the joint carries (Young's modulus × second moment of area)", magnitude=True),
    # wrist cross coupling (section 4.7)
    Kind(r"coupling\.sigma(?P<j>\d)(?P<k>\d)", "coupling σ{j#}{k#} ({k} per {j})", "deg/deg", 1.0,
         "degrees {k}'s encoder reads per degree {j} turns (eq 4.7.1)", magnitude=True),
    Kind(r"coupling\.further(?P<j>\d)(?P<k>\d)", "further coupling correction σ{j#}{k#}", "deg/deg", 1.0,
         "what the model must add to the controller's own σ{j#}{k#}: measured less the description's (eq 4.7.2)"),
    # encoder resolution (Fig 5.14)
    Kind(rf"resolution\.{_J}\.rad_per_count", "{j} encoder resolution", "arcsec/count", ARCSEC,
         "joint angle per encoder count, from the slope of the measured angle against the counts"),
    Kind(rf"resolution\.{_J}\.scale", "{j} resolution against its description", "", 1.0,
         "measured resolution divided by the description's (1: gear ratio and counts per turn as described)"),
    Kind(rf"resolution\.{_J}\.offset_rad", "{j} resolution line's offset", "deg", DEG,
         "the fitted line's angle at zero counts"),
    # the pose set (Chapter 6)
    *[Kind(rf"ident\.base\.{a}_mm", f"robot base position {a}", "mm", 1.0,
           f"{a} of the robot's base frame in the instruments' frame") for a in _XYZ],
    *[Kind(rf"ident\.base\.{suffix}", f"robot base {words}", "deg", DEG,
           f"{words.split()[0]} of the robot's base frame in the instruments' frame") for suffix, words in _RPY.items()],
    *[Kind(rf"ident\.tool\.{a}_mm", f"tool point {a}", "mm", 1.0, f"{a} of the sighted tool target in the flange's "
           f"frame") for a in _XYZ],
    Kind(rf"ident\.transmission_error\.{_J}\.s(?P<h>\d+)_rad", "{j} transmission error, sine term {h}", "deg", DEG,
         "coefficient of sin(harmonic {h}) of the joint's transmission error, fitted with the pose set"),
    Kind(rf"ident\.transmission_error\.{_J}\.c(?P<h>\d+)_rad", "{j} transmission error, cosine term {h}", "deg", DEG,
         "coefficient of cos(harmonic {h}) of the joint's transmission error, fitted with the pose set"),
    Kind(rf"ident\.joint_compliance\.{_J}\.compliance1_rad_per_nm", "{j} compliance", "deg/(N m)", DEG,
         "deflection of the joint per N m of torque about it (the inverse of its stiffness), fitted with the pose "
         "set", magnitude=True),
    Kind(rf"ident\.joint_compliance\.{_J}\.compliance2_rad_per_nm", "{j} compliance above the breakpoint",
         "deg/(N m)", DEG, "deflection per N m above the breakpoint torque", magnitude=True),
    Kind(rf"ident\.joint_compliance\.{_J}\.breakpoint_nm", "{j} compliance breakpoint", "N m", 1.0,
         "torque at which the joint's compliance changes", magnitude=True),
    Kind(rf"ident\.joint_compliance\.{_J}\.deadzone_rad", "{j} dead zone", "deg", DEG,
         "free play of the joint about zero torque"),
    Kind(rf"ident\.cross_coupling\.{_J}{_K}\.sigma", "coupling σ{j#}{k#} ({k} per {j}), from the poses", "deg/deg",
         1.0, "degrees {k} turns per degree {j} turns beyond the description's coupling, fitted with the pose set"),
    Kind(rf"ident\.backlash\.{_J}\.width_rad", "{j} backlash", "deg", DEG,
         "lost motion of the joint when its direction of approach reverses"),
    Kind(rf"ident\.joint_scale\.{_J}\.scale", "{j} angle scale error", "", 1.0,
         "share by which the joint turns more than its reading says"),
]
_COMPILED = [(re.compile(k.pattern + r"\Z"), k) for k in KINDS]


def joint_words(labels, j: int) -> str:
    """Joint ``j`` (1-based) in a name: the session's label (``joint 4``, ``arm_4_joint``), ``joint 4`` without."""
    labels = list(labels or ())
    return labels[j - 1] if 1 <= j <= len(labels) else f"joint {j}"


def _fill(text: str, groups: dict, labels) -> str:
    out = text
    for key, val in groups.items():
        if val is None:
            continue
        if key in ("j", "k"):
            out = out.replace(f"{{{key}#}}", val).replace(f"{{{key}}}", joint_words(labels, int(val)))
        else:
            out = out.replace(f"{{{key}}}", val)
    return out


def describe(code: str, labels=None) -> Described:
    """The code name ``code`` (a results document's estimate or bound name) as a person reads it; ``labels``: the
    joints as the session names them (``joint_labels`` of the results document).  Kept per (code, labels): a
    summary asks for each estimate's words about five times (its section, verdict, name, unit, meaning), and the
    answer depends on nothing else (the kinds are this module's constants; :class:`Described` is frozen)."""
    return _describe(code, None if labels is None else tuple(labels))


@lru_cache(maxsize=4096)
def _describe(code: str, labels: tuple | None) -> Described:
    for rx, kind in _COMPILED:
        m = rx.match(code)
        if m:
            g = m.groupdict()
            return Described(_fill(kind.name, g, labels), kind.unit, kind.scale, _fill(kind.meaning, g, labels),
                             kind.magnitude)
    return _fallback(code, labels)


_SUFFIX = re.compile(r"_(rad_per_nm|per_nmm2|per_degc|kgmm|kg|mm|rad|nm|Nm_per_rad|Nmm2|Nm)\Z")
_JOINT = re.compile(r"j(\d+)\Z")
_PAIR = re.compile(r"j(\d+)j(\d+)\Z")


def _fallback(code: str, labels) -> Described:
    """A code name no kind knows, in words: the section's prefix dropped, joints named, underscores as spaces."""
    unit, scale = edge_unit(unit_of(code))
    words = []
    for tok in _SUFFIX.sub("", code).split(".")[1:] or [code]:
        if _JOINT.match(tok):
            words.append(joint_words(labels, int(tok[1:])))
        elif _PAIR.match(tok):
            a, b = _PAIR.match(tok).groups()
            words.append(f"{joint_words(labels, int(a))}–{joint_words(labels, int(b))}")
        else:
            words.append(tok.replace("_", " "))
    return Described(" ".join(words), "" if unit == "1" else unit, scale, "")
