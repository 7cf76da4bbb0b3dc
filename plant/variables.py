"""The one table of the plant FMU's variables (docs/design.md §4).

Everything that names a variable is generated from this table: the C structs the physics works on and
the value-reference switch of the FMI wrapper (``quadrotor_vars.h``), and ``modelDescription.xml``.
Adding a variable here and rebuilding is the whole change; the C compiler then refuses physics code that
uses a field the table does not declare. Names, units and defaults are a public interface: scenarios,
tests and outside tools address variables by name.
"""

from __future__ import annotations

import hashlib
import math
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal
from xml.sax.saxutils import quoteattr

Causality = Literal["input", "parameter", "output"]
VarType = Literal["Real", "Integer", "Boolean"]

MODEL_IDENTIFIER = "quadrotor"
MODEL_NAME = "quadrotor"

#: Standard gravity, also the default of the ``gravity`` parameter (docs/sensors.md §6).
G0 = 9.80665


@dataclass(frozen=True)
class Range:
    """The values a parameter may take: the FMU refuses others at initialisation (its own check is
    generated from this), ``modelDescription.xml`` declares the closed bounds as min/max, and the
    scenario checker refuses them before anything runs. Every parameter must also be finite."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False   # low itself excluded (mass > 0)
    high_open: bool = False
    text: str = ""           # how the FMU says it ("must be " + text); generated when empty

    def holds(self, v: float) -> bool:
        return (math.isfinite(v) and (v > self.low if self.low_open else v >= self.low)
                and (v < self.high if self.high_open else v <= self.high))

    def says(self) -> str:
        if self.text:
            return self.text
        if -math.inf < self.low and self.high < math.inf and not (self.low_open or self.high_open):
            return f"{self.low:g}..{self.high:g}"
        lo = f"{'>' if self.low_open else '>='} {self.low:g}" if self.low > -math.inf else ""
        hi = f"{'<' if self.high_open else '<='} {self.high:g}" if self.high < math.inf else ""
        return " and ".join(x for x in (lo, hi) if x) or "finite"


FINITE = Range()
POSITIVE = Range(0.0, low_open=True)
NON_NEGATIVE = Range(0.0)


@dataclass(frozen=True)
class Variable:
    """One FMI scalar variable and the C struct field that holds it."""

    name: str
    causality: Causality
    type: VarType
    start: float
    unit: str
    description: str
    field: str  # C field inside qr_inputs / qr_params / qr_outputs, e.g. "pwm_us[0]"
    valid: Range = FINITE  # parameters: the values the FMU accepts


def _v(name: str, causality: Causality, start: float, unit: str, description: str,
       field: str | None = None, type: VarType = "Real", valid: Range = FINITE) -> Variable:
    return Variable(name, causality, type, start, unit, description, field or name, valid)


#: The rotors, numbered 1..MOTORS in the "+" order of docs/design.md §3 (1 front, 2 left, 3 rear,
#: 4 right): each has an ESC input ``pwm{m}_us``, a health input ``motor_health{m}`` and outputs
#: ``omega{m}`` and ``thrust{m}``. Everything that counts motors counts them from here.
MOTORS = 4


def pwm_input(motor: int) -> str:
    """The ESC pulse-width input of motor ``motor`` (1..MOTORS)."""
    return f"pwm{motor}_us"


def _four(stem: str, causality: Causality, start: float, unit: str, description: str,
          field: str, suffix: str = "") -> list[Variable]:
    return [_v(f"{stem}{i}{suffix}", causality, start, unit, f"{description}, motor {i}",
               f"{field}[{i - 1}]") for i in range(1, MOTORS + 1)]


def _axes(names: tuple[str, str, str], causality: Causality, start: tuple[float, float, float],
          unit: str, description: str, field: str, valid: Range = FINITE) -> list[Variable]:
    return [_v(n, causality, s, unit, f"{description} ({n.rsplit('_', 1)[-1]})", f"{field}[{k}]",
               valid=valid) for k, (n, s) in enumerate(zip(names, start, strict=True))]


_INPUTS: list[Variable] = [
    *_four("pwm", "input", 1000.0, "us", "ESC pulse width", "pwm_us", "_us"),
    *_axes(("wind_n", "wind_e", "wind_d"), "input", (0, 0, 0), "m/s", "wind velocity, world NED",
           "wind"),
    *_axes(("f_ext_n", "f_ext_e", "f_ext_d"), "input", (0, 0, 0), "N", "external force, world NED",
           "f_ext"),
    *_axes(("tau_ext_x", "tau_ext_y", "tau_ext_z"), "input", (0, 0, 0), "N.m",
           "external torque, body FRD", "tau_ext"),
    *_four("motor_health", "input", 1.0, "1",
           "rotor effectiveness (multiplies thrust and reaction torque; clamped to >= 0)",
           "motor_health"),
]

_PARAMETERS: list[Variable] = [
    _v("mass", "parameter", 1.2, "kg", "vehicle mass (seed 001 Table 1)", valid=POSITIVE),
    _v("arm_length", "parameter", 0.2, "m", "rotor centre to centre of mass (seed 001 Table 1)",
       valid=POSITIVE),
    _v("k_thrust", "parameter", 3.13e-5, "N.s2", "thrust = k_thrust * omega^2 (seed 001 Table 1)",
       valid=NON_NEGATIVE),
    _v("k_torque", "parameter", 7.5e-7, "N.m.s2",
       "reaction torque = k_torque * omega^2 (seed 001 Table 1)", valid=NON_NEGATIVE),
    _v("Ixx", "parameter", 2.353e-3, "kg.m2", "roll inertia (seed 001 Table 1)", valid=POSITIVE),
    _v("Iyy", "parameter", 2.353e-3, "kg.m2", "pitch inertia (seed 001 Table 1)", valid=POSITIVE),
    _v("Izz", "parameter", 5.262e-2, "kg.m2", "yaw inertia (seed 001 Table 1)", valid=POSITIVE),
    _v("frame", "parameter", 0, "",
       "0 '+' frame (1 front, 2 left, 3 rear, 4 right); 1 X frame (the '+' layout turned 45 deg "
       "clockwise seen from above: 1 front-right, 2 front-left, 3 rear-left, 4 rear-right)",
       type="Integer", valid=Range(0, 1, text="0 (+) or 1 (X)")),
    _v("motor_tau", "parameter", 0.02, "s", "first-order motor time constant", valid=POSITIVE),
    _v("omega_max", "parameter", 600.0, "rad/s", "rotor speed at full throttle", valid=POSITIVE),
    _v("esc_min_us", "parameter", 1000.0, "us", "pulse width for zero throttle"),
    _v("esc_max_us", "parameter", 2000.0, "us", "pulse width for full throttle"),
    _v("esc_start_us", "parameter", 1000.0, "us",
       "ESC start threshold: below this pulse width the motor does not spin (commanded speed 0); "
       "at and above it the ESC curve applies"),
    *_four("esc_gain", "parameter", 1.0, "1",
           "ESC curve gain: omega_cmd = omega_max * clamp(gain * u + offset, 0, 1)", "esc_gain"),
    *_four("esc_offset", "parameter", 0.0, "1",
           "ESC curve offset: omega_cmd = omega_max * clamp(gain * u + offset, 0, 1)",
           "esc_offset"),
    *_axes(("drag_n", "drag_e", "drag_d"), "parameter", (0.25, 0.25, 0.25), "N.s/m",
           "linear drag on air-relative velocity, world axis", "drag", valid=NON_NEGATIVE),
    _v("gravity", "parameter", G0, "m/s2", "gravitational acceleration", valid=NON_NEGATIVE),
    _v("stand", "parameter", 0, "",
       "0 free flight, 1 roll gimbal, 2 pitch gimbal, 3 yaw gimbal, 4 attitude gimbal "
       "(gimbals hold the position fixed)", type="Integer", valid=Range(0, 4)),
    _v("stand_damping", "parameter", 0.0, "N.m.s/rad", "viscous friction of the stand's bearings",
       valid=NON_NEGATIVE),
    _v("roll0", "parameter", 0.0, "rad", "initial roll"),
    _v("pitch0", "parameter", 0.0, "rad", "initial pitch"),
    _v("yaw0", "parameter", 0.0, "rad", "initial yaw"),
    _v("pn0", "parameter", 0.0, "m", "initial north position"),
    _v("pe0", "parameter", 0.0, "m", "initial east position"),
    _v("pd0", "parameter", 0.0, "m",
       "initial down position (the ground is pd = 0; free flight needs pd0 <= 0)"),
    *_axes(("mag_n", "mag_e", "mag_d"), "parameter", (0.25, 0.0, 0.433), "G",
           "Earth magnetic field, world NED", "mag"),
    _v("p_ground", "parameter", 101325.0, "Pa", "static pressure at pd = 0", valid=POSITIVE),
    _v("t_ground", "parameter", 15.0, "degC", "air temperature at pd = 0",
       valid=Range(-273.15, low_open=True, text="above absolute zero (-273.15 degC)")),
    _v("h_max_step", "parameter", 1e-3, "s", "longest internal RK4 sub-step",
       valid=Range(0.0, 0.1, low_open=True)),
]

_OUTPUTS: list[Variable] = [
    *_axes(("pn", "pe", "pd"), "output", (0, 0, 0), "m", "position, world NED", "pos"),
    *_axes(("vn", "ve", "vd"), "output", (0, 0, 0), "m/s", "velocity, world NED", "vel"),
    *[_v(n, "output", 0.0, "1", f"attitude quaternion body to world, scalar first ({n})",
         f"q[{k}]") for k, n in enumerate(("qw", "qx", "qy", "qz"))],
    _v("roll", "output", 0.0, "rad", "Euler ZYX roll (right wing down positive)"),
    _v("pitch", "output", 0.0, "rad", "Euler ZYX pitch (nose up positive)"),
    _v("yaw", "output", 0.0, "rad", "Euler ZYX yaw (nose right positive)"),
    *[_v(n, "output", 0.0, "rad/s", f"body angular rate ({n})", f"rate[{k}]")
      for k, n in enumerate(("p", "q", "r"))],
    *[_v(n, "output", 0.0, "m/s2", "specific force (what an accelerometer measures), body FRD "
         f"({n})", f"f_body[{k}]") for k, n in enumerate(("fx", "fy", "fz"))],
    *[_v(n, "output", 0.0, "G", f"Earth magnetic field in body FRD ({n})", f"mag_body[{k}]")
      for k, n in enumerate(("mag_x", "mag_y", "mag_z"))],
    _v("pressure", "output", 0.0, "Pa", "static pressure (ISA troposphere from altitude)"),
    _v("temperature", "output", 0.0, "degC", "air temperature (ISA lapse from altitude)"),
    *_four("omega", "output", 0.0, "rad/s", "rotor speed", "omega"),
    *_four("thrust", "output", 0.0, "N", "rotor thrust", "thrust"),
    _v("on_ground", "output", 0, "", "resting on the ground (free flight only)", type="Boolean"),
]

VARIABLES: list[Variable] = [*_INPUTS, *_PARAMETERS, *_OUTPUTS]

#: Value references: Reals, Integers and Booleans each count from their own base.
_VR_BASE: dict[VarType, int] = {"Real": 0, "Integer": 1000, "Boolean": 2000}


PARAMETERS: dict[str, Variable] = {v.name: v for v in VARIABLES if v.causality == "parameter"}
PWM_INPUTS = tuple(pwm_input(m) for m in range(1, MOTORS + 1))
#: The inputs a scenario sets (wind, external force and torque, motor health); the motors' pulse widths
#: come from the DUT
SCENARIO_INPUTS = tuple(v.name for v in VARIABLES if v.causality == "input" and v.name not in PWM_INPUTS)


#: Seed 001's Table 1 inertia, the plant's default (plant/airframes/seed-001.toml): Izz exceeds
#: Ixx + Iyy, which no rigid body can have. It alone is exempt from the triangle rule, so that the seed
#: scenarios keep flying the seed's vehicle; every report that flies it says so.
SEED_INERTIA: tuple[float, float, float] = (PARAMETERS["Ixx"].start, PARAMETERS["Iyy"].start,
                                            PARAMETERS["Izz"].start)
#: Relative slack of the triangle rule: a flat plate has Izz = Ixx + Iyy exactly, up to rounding
TRIANGLE_SLACK = 1e-9


def triangle_broken(ixx: float, iyy: float, izz: float) -> str | None:
    """Why principal moments of inertia cannot belong to a rigid body, or None. Each must be at most
    the sum of the other two (Izz = integral of x^2 + y^2 dm = Ixx + Iyy - 2 integral of z^2 dm, and so
    for every axis). The FMU applies the same rule, in the same words (qr_check_params)."""
    moments = {"Ixx": ixx, "Iyy": iyy, "Izz": izz}
    for name, value in moments.items():
        a, b = (n for n in moments if n != name)
        if value > (moments[a] + moments[b]) * (1 + TRIANGLE_SLACK):
            return (f"{name} must be <= {a} + {b} (the triangle inequality of a rigid body's principal "
                    "moments of inertia)")
    return None


def inertia_refused(ixx: float, iyy: float, izz: float) -> str | None:
    """The plant's rule: :func:`triangle_broken`, except for seed 001's inertia (kept for the seed
    scenarios)."""
    return None if (ixx, iyy, izz) == SEED_INERTIA else triangle_broken(ixx, iyy, izz)


def check_parameters(values: Mapping[str, float]) -> str | None:
    """Why the FMU would refuse these parameter values at initialisation (its words), or None. The
    names must be parameters; the others keep their start values. The same rules as the FMU's own
    check (``qr_check_params``: the ranges above, generated into C, then two that relate parameters);
    tests/plant/test_bad_input.py holds the two against each other."""
    p = {name: v.start for name, v in PARAMETERS.items()} | dict(values)
    for name, v in PARAMETERS.items():
        if not v.valid.holds(p[name]):
            return f"{name} must be {v.valid.says()}"
        if v.type == "Integer" and p[name] != int(p[name]):
            return f"{name} takes a whole number"
    if not p["esc_max_us"] > p["esc_min_us"]:
        return "esc_max_us must be > esc_min_us"
    refused = inertia_refused(p["Ixx"], p["Iyy"], p["Izz"])
    if refused:
        return refused
    if p["stand"] == 0 and p["pd0"] > 0:
        return "pd0 must be <= 0 in free flight (the ground is at pd = 0)"
    return None


def _c_number(x: float) -> str:
    return "INFINITY" if x == math.inf else "-INFINITY" if x == -math.inf else repr(float(x))


def value_references() -> dict[str, int]:
    """Name -> FMI value reference, in table order within each type."""
    counters = dict(_VR_BASE)
    refs = {}
    for v in VARIABLES:
        refs[v.name] = counters[v.type]
        counters[v.type] += 1
    return refs


_STRUCTS: dict[Causality, str] = {"input": "qr_inputs", "parameter": "qr_params",
                                  "output": "qr_outputs"}
_KIND: dict[Causality, str] = {"input": "INPUT", "parameter": "PARAM", "output": "OUTPUT"}
_C_TYPE: dict[VarType, str] = {"Real": "double", "Integer": "int", "Boolean": "int"}

# Units in modelDescription, with their SI base units (FMI 2 §2.2.2).
_UNITS: dict[str, str] = {
    "us": 's="1" factor="1e-6"', "m/s": 'm="1" s="-1"', "N": 'kg="1" m="1" s="-2"',
    "N.m": 'kg="1" m="2" s="-2"', "1": "", "kg": 'kg="1"', "m": 'm="1"',
    "N.s2": 'kg="1" m="1"', "N.m.s2": 'kg="1" m="2"', "kg.m2": 'kg="1" m="2"', "s": 's="1"',
    "rad/s": 'rad="1" s="-1"', "N.s/m": 'kg="1" s="-1"', "m/s2": 'm="1" s="-2"',
    "N.m.s/rad": 'kg="1" m="2" s="-1" rad="-1"', "rad": 'rad="1"', "G": 'kg="1" s="-2" A="-1" factor="1e-4"',
    "Pa": 'kg="1" m="-1" s="-2"', "degC": 'K="1" offset="273.15"',
}


def _fmt(v: Variable) -> str:
    if v.type == "Real":
        return repr(float(v.start))
    return str(int(v.start))


def _struct_fields(causality: Causality) -> list[str]:
    """C declarations for one struct: indexed fields become arrays sized by their largest index."""
    sizes: dict[str, int] = {}
    types: dict[str, str] = {}
    for v in VARIABLES:
        if v.causality != causality:
            continue
        base, _, idx = v.field.partition("[")
        sizes[base] = max(sizes.get(base, 0), int(idx.rstrip("]")) + 1 if idx else 0)
        types[base] = _C_TYPE[v.type]
    return [f"    {types[b]} {b}{f'[{n}]' if n else ''};" for b, n in sizes.items()]


def guid() -> str:
    """A GUID that changes exactly when the variable interface changes (deterministic builds)."""
    digest = hashlib.sha256(repr(VARIABLES).encode()).hexdigest()
    return "{" + str(uuid.uuid5(uuid.NAMESPACE_OID, digest)) + "}"


def c_header() -> str:
    """The generated C header: structs for the physics and X-macro lists for the FMI wrapper."""
    refs = value_references()
    out = ["/* Generated by plant/variables.py: do not edit. */",
           "#ifndef QUADROTOR_VARS_H", "#define QUADROTOR_VARS_H", "",
           f'#define QR_GUID "{guid()}"', f'#define QR_MODEL_IDENTIFIER "{MODEL_IDENTIFIER}"', ""]
    for causality, struct in _STRUCTS.items():
        out += ["typedef struct {", *_struct_fields(causality), f"}} {struct};", ""]
    for vtype in ("Real", "Integer", "Boolean"):
        rows = [v for v in VARIABLES if v.type == vtype]
        out.append(f"#define QR_{vtype.upper()}_VR_BASE {_VR_BASE[vtype]}")
        out.append(f"#define QR_NUM_{vtype.upper()} {len(rows)}")
        out.append(f"/* X(vr, field, KIND, start, name) */\n#define QR_{vtype.upper()}_VARIABLES(X) \\")
        out += [f'    X({refs[v.name]}, {v.field}, {_KIND[v.causality]}, {_fmt(v)}, "{v.name}") \\'
                for v in rows]
        out.append("")
    out.append("/* Parameter ranges (qr_check_params):")
    out.append("   CHECK(field, low, low_open, high, high_open, message) */")
    out.append("#define QR_PARAM_RANGES(CHECK) \\")
    out += [f"    CHECK({v.field}, {_c_number(v.valid.low)}, {int(v.valid.low_open)}, "
            f"{_c_number(v.valid.high)}, {int(v.valid.high_open)}, "
            f'"{v.name} must be {v.valid.says()}") \\'
            for v in PARAMETERS.values()]
    out += ["", "/* Seed 001's inertia, the one exempt from the triangle rule (plant/variables.py) */",
            f"#define QR_SEED_IXX {SEED_INERTIA[0]!r}", f"#define QR_SEED_IYY {SEED_INERTIA[1]!r}",
            f"#define QR_SEED_IZZ {SEED_INERTIA[2]!r}", f"#define QR_TRIANGLE_SLACK {TRIANGLE_SLACK!r}",
            "", "#endif", ""]
    return "\n".join(out)


def model_description() -> str:
    """modelDescription.xml (FMI 2.0 co-simulation); no timestamps, so builds are reproducible."""
    refs = value_references()
    units = sorted({v.unit for v in VARIABLES if v.unit})
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0" modelName="{MODEL_NAME}" guid="{guid()}"',
        '  description="Quadrotor 6-DOF plant for hardware-in-the-loop testing (NED world, FRD body)"',
        '  generationTool="plant/build.py" variableNamingConvention="flat" numberOfEventIndicators="0">',
        f'  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true"',
        '    canGetAndSetFMUstate="true" canSerializeFMUstate="true"',
        '    canNotUseMemoryManagementFunctions="true"/>',
        "  <UnitDefinitions>",
        *[f'    <Unit name="{u}"><BaseUnit {_UNITS[u]}/></Unit>' if _UNITS[u]
          else f'    <Unit name="{u}"/>' for u in units],
        "  </UnitDefinitions>",
        "  <LogCategories>",
        '    <Category name="logStatusWarning" description="bad input that was clamped or rejected"/>',
        '    <Category name="logStatusError" description="calls that failed and changed nothing"/>',
        "  </LogCategories>",
        '  <DefaultExperiment startTime="0" stopTime="10" stepSize="0.001"/>',
        "  <ModelVariables>",
    ]
    for v in VARIABLES:
        attrs = f'name="{v.name}" valueReference="{refs[v.name]}" causality="{v.causality}"'
        if v.causality == "parameter":
            attrs += ' variability="fixed" initial="exact"'
        elif v.type == "Real":
            attrs += ' variability="continuous"'
        else:
            attrs += ' variability="discrete"'
        attrs += f" description={quoteattr(v.description)}"
        type_attrs = f' unit="{v.unit}"' if v.unit and v.type == "Real" else ""
        if v.causality == "parameter":  # the closed bounds (FMI's min and max include themselves)
            if v.valid.low > -math.inf and not v.valid.low_open:
                type_attrs += f' min="{v.valid.low:g}"'
            if v.valid.high < math.inf and not v.valid.high_open:
                type_attrs += f' max="{v.valid.high:g}"'
        if v.causality != "output":
            type_attrs += f' start="{_fmt(v)}"'
        lines.append(f"    <ScalarVariable {attrs}><{v.type}{type_attrs}/></ScalarVariable>")
    outputs = [i for i, v in enumerate(VARIABLES, start=1) if v.causality == "output"]
    lines += [
        "  </ModelVariables>",
        "  <ModelStructure>",
        "    <Outputs>", *[f'      <Unknown index="{i}"/>' for i in outputs], "    </Outputs>",
        "    <InitialUnknowns>", *[f'      <Unknown index="{i}"/>' for i in outputs],
        "    </InitialUnknowns>",
        "  </ModelStructure>",
        "</fmiModelDescription>",
        "",
    ]
    return "\n".join(lines)
