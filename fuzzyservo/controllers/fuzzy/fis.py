"""MATLAB ``.fis`` text (Fuzzy Logic Toolbox format) ⇄ :class:`FuzzySystem`.

The format is the one ``readfis``/``writefis`` use (Fuzzy Logic Toolbox User's Guide,
"The FIS Structure — Saving FIS Files on Disk"; unchanged in R2018b+ files apart from
a ``Version=2.0`` line)::

    [System]
    Name='tipper'
    Type='mamdani'
    Version=2.0
    NumInputs=2
    NumOutputs=1
    NumRules=3
    AndMethod='min'
    OrMethod='max'
    ImpMethod='min'
    AggMethod='max'
    DefuzzMethod='centroid'

    [Input1]
    Name='service'
    Range=[0 10]
    NumMFs=3
    MF1='poor':'gaussmf',[1.5 0]
    ...

    [Output1]
    ...

    [Rules]
    1 1, 1 (1) : 2

A rule line is: one MF number per input (1-based, ``0`` no condition, ``-k`` NOT MF
k), a comma, one MF number per output (``0`` none, ``-k`` NOT MF k), the weight in
parentheses, a colon and the connective (``1`` AND, ``2`` OR). Numbers may be written
with decimals (``1.000 1.000, 1.000 (1.000) : 2``, as fuzzylite writes them).

Supported: everything the Fuzzy Logic Toolbox writes for type-1 systems — Mamdani and
Sugeno (``constant`` and ``linear`` output terms, ``wtaver``/``wtsum``), any number of
inputs and outputs, every built-in membership function (:mod:`.shapes`; extra
parameters are kept and ignored, as MATLAB does), rule weights, NOT, negated
consequents, empty method names (MATLAB's defaults). Anything else (type-2 systems,
custom method functions, fuzzylite-only shapes) is a :class:`ConfigError` naming the
file, the line and section, the problem and the fix.

The format has no evaluation settings; fuzzyservo writes its own in a comment line
MATLAB skips, ``% fuzzyservo: semantics=skfuzzy sample_points=101 points=201``
(``points``: universe samples of the ``skfuzzy`` semantics, per variable when they
differ), so a round trip is lossless. Files without it get the defaults.

The text is read line by line in ``_fis_reader`` (sections, keys, values, each problem
located) and its sections become variables, terms and rules in ``_fis_system``; this
module parses and writes the text, and the control law a controller's file carries.
Pure text ⇄ objects, as fuzzylite's importers and exporters are: the files are read and
written by :mod:`fuzzyservo.io.fuzzy_files`.
"""

from __future__ import annotations

from pathlib import Path

from fuzzyservo.controllers.fuzzy._fis_reader import _METHODS, _TAG, LAW_KEYS, _Reader
from fuzzyservo.controllers.fuzzy._fis_system import _count, _numbered, _rule, _variable, _with_fix
from fuzzyservo.controllers.fuzzy.controller import FuzzyController
from fuzzyservo.controllers.fuzzy.system import (
    MATLAB_SAMPLE_POINTS,
    SEMANTICS,
    FuzzySystem,
    Variable,
    to_matlab,
)
from fuzzyservo.errors import ConfigError, excerpt
from fuzzyservo.limits import MAX_SAMPLE_POINTS

__all__ = [
    "LAW_KEYS", "controller_from_law", "fis_text", "law_text", "number_text", "parse_fis",
    "parse_fis_controller", "parse_fis_law",
]  # fmt: skip

#: the ``Version`` written by :func:`fis_text` (MATLAB R2018b and later)
VERSION = "2.0"
_SYSTEM_KEYS = ("Name", "Type", "Version", "NumInputs", "NumOutputs", "NumRules", *_METHODS)


def parse_fis(text: str, file: str = "<fis text>", points: int = 201) -> FuzzySystem:
    """The :class:`FuzzySystem` in ``.fis`` text (module docstring); errors name ``file``.

    Universes get ``points`` evenly spaced samples unless the file's ``% fuzzyservo:``
    line says otherwise.
    """
    return parse_fis_law(text, file, points)[0]


def parse_fis_law(
    text: str, file: str = "<fis text>", points: int = 201
) -> tuple[FuzzySystem, dict[str, str]]:
    """The system of ``.fis`` text and the control law (:data:`LAW_KEYS`, as text) its
    ``% fuzzyservo:`` line gives (empty when it gives none)."""
    reader = _Reader(file)
    sections = reader.sections(text)
    if "System" not in sections:
        reader.fail(
            "no [System] section; is this a MATLAB .fis file? Add [System] with Type='mamdani'",
            "[System]",
        )
    system = sections["System"]
    for key, entry in system.entries.items():
        if key not in _SYSTEM_KEYS:
            reader.fail(
                f"unknown key {excerpt(key)} (known: {', '.join(_SYSTEM_KEYS)}); remove it",
                f"[System].{key}",
                entry.number,
            )
    if "Type" not in system.entries:
        reader.fail("missing Type; add Type='mamdani'", "[System]", system.number)
    fis_type = reader.text(system, "Type").strip().lower()
    if fis_type not in ("mamdani", "sugeno"):
        reader.fail(
            f"unsupported FIS type {excerpt(fis_type)} (supported: mamdani, sugeno — type-1 systems; "
            f"{'type-2 systems' if 'type2' in fis_type else 'this type'} cannot be read); "
            "convert it to a type-1 Mamdani or Sugeno system",
            "[System].Type",
            system.entries["Type"].number,
        )
    sugeno = fis_type == "sugeno"
    if "Version" in system.entries:
        reader.numbers(
            system.entries["Version"].value,
            "[System].Version",
            system.entries["Version"].number,
            "write it like Version=2.0",
        )
    input_names = _numbered(reader, sections, "Input")
    output_names = _numbered(reader, sections, "Output")
    if not input_names:
        reader.fail("no [Input1] section; add the input variable", "[System]", system.number)
    if not output_names:
        reader.fail("no [Output1] section; add the output variable", "[System]", system.number)
    if "Rules" not in sections:
        reader.fail("no [Rules] section; add the rule base", "[System]", system.number)
    _count(reader, system, "NumInputs", len(input_names), "input sections")
    _count(reader, system, "NumOutputs", len(output_names), "output sections")
    methods = {attr: reader.method(system, key, sugeno) for key, (attr, _) in _METHODS.items()}
    points = reader.setting_int("points", points)
    in_defaults = ("e", "de") if len(input_names) <= 2 else ()
    inputs = [
        _variable(
            reader,
            sections[n],
            in_defaults[k] if k < len(in_defaults) else f"input{k + 1}",
            reader.setting_int(f"{n}.points", points),
            False,
        )
        for k, n in enumerate(input_names)
    ]
    outputs = [
        _variable(
            reader,
            sections[n],
            "u" if len(output_names) == 1 else f"output{k + 1}",
            reader.setting_int(f"{n}.points", points),
            sugeno,
        )
        for k, n in enumerate(output_names)
    ]
    rule_lines = sections["Rules"].lines
    if not rule_lines:
        reader.fail("the rule base is empty; add rule lines", "[Rules]", sections["Rules"].number)
    _count(reader, system, "NumRules", len(rule_lines), "rule lines")
    rules = tuple(_rule(reader, line, inputs, outputs, sugeno) for line in rule_lines)
    name = reader.text(system, "Name") if "Name" in system.entries else Path(file).stem
    semantics = "skfuzzy"
    if "semantics" in reader.settings:
        semantics, line = reader.settings["semantics"]
        if semantics not in SEMANTICS:
            reader.fail(
                f"semantics must be one of {list(SEMANTICS)}, got {excerpt(semantics)}", line=line
            )
    law = {k: v for k, (v, _) in reader.settings.items() if k in LAW_KEYS}
    sample_points = reader.setting_int("sample_points", MATLAB_SAMPLE_POINTS, MAX_SAMPLE_POINTS)
    try:
        return FuzzySystem(
            name=name,
            inputs=tuple(inputs),
            output=outputs[0],
            other_outputs=tuple(outputs[1:]),
            rules=rules,
            type=fis_type,
            semantics=semantics,
            sample_points=sample_points,
            **methods,
        ), law
    except ValueError as exc:
        reader.fail(_with_fix(exc, "fix the file"), "[System]", system.number)


def parse_fis_controller(text: str, file: str) -> FuzzyController:
    """A controller from ``.fis`` text (a file or an upload named ``file``): the control
    law its ``% fuzzyservo:`` line gives (:func:`law_text`, what ``fuzzyservo export``
    writes), else one input → form ``p``, two → ``pd``, all gains 1 and no output limits
    (the simulator applies the rig actuator's command range). Named after the file stem.
    """
    system, law = parse_fis_law(text, file)
    return controller_from_law(system, law, Path(file), "[Rules]")


def law_text(controller: FuzzyController) -> str:
    """The control law around the inference system (form, gains, output limits) as the
    ``key=value`` pairs a ``% fuzzyservo:`` line (``.fis``) or ``(* fuzzyservo: *)``
    comment (FCL) carries, numbers exact (``repr``)."""
    values = [number_text(getattr(controller, k)) for k in LAW_KEYS[1:]]
    pairs = [
        f"form={controller.form}",
        *(f"{k}={v}" for k, v in zip(LAW_KEYS[1:], values, strict=True)),
    ]
    return " ".join(pairs)


def controller_from_law(
    system: FuzzySystem, law: dict[str, str], path: Path, key: str
) -> FuzzyController:
    """The controller of ``system`` with the control law ``law`` (:data:`LAW_KEYS`, as
    text; missing keys: the form from the number of inputs, gains 1, no limits)."""
    settings: dict[str, object] = {}
    for k, text in law.items():
        if k == "form":
            settings[k] = text
            continue
        try:
            settings[k] = float(text)
        except ValueError:
            raise ConfigError(
                f"control law {k}={excerpt(text)} is not a number; write it like {k}=1.5",
                file=str(path), key="fuzzyservo control law",
            ) from None  # fmt: skip
    settings.setdefault("form", "p" if len(system.inputs) == 1 else "pd")
    kind = "MATLAB FIS" if path.suffix.lower() == ".fis" else "FCL function block"
    try:
        return FuzzyController(
            system=system,
            name=path.stem,
            description=f"{kind} {system.name!r} read from {path.name}",
            **settings,  # type: ignore[arg-type]
        )
    except ValueError as exc:
        raise ConfigError(_with_fix(exc, "fix the rules"), file=str(path), key=key) from None


# --------------------------------------------------------------------------- writing
def number_text(x: float) -> str:
    """Shortest text that reads back as the same float (``repr``), ``1.0`` written ``1``."""
    text = repr(float(x))
    return text[:-2] if text.endswith(".0") else text


def _quoted(name: str, what: str) -> str:
    if "'" in name or "\n" in name or "\r" in name:
        raise ValueError(
            f"{what} {excerpt(name)} cannot be written to a .fis file (names are quoted with ' and "
            "on one line); rename it"
        )
    return f"'{name}'"


def _variable_text(section: str, var: Variable, points: int) -> list[str]:
    lines = [f"[{section}]"]
    if var.points != points:
        lines.append(f"{_TAG} points={var.points}")
    lines += [
        f"Name={_quoted(var.name, 'variable name')}",
        f"Range=[{number_text(var.low)} {number_text(var.high)}]",
        f"NumMFs={len(var.terms)}",
    ]
    for k, t in enumerate(var.terms, start=1):
        params = " ".join(number_text(p) for p in t.params)
        lines.append(f"MF{k}={_quoted(t.name, 'term name')}:'{t.shape}',[{params}]")
    return [*lines, ""]


def fis_text(system: FuzzySystem, law: str = "") -> str:
    """``system`` as MATLAB ``.fis`` text (R2018b+ layout, ``Version=2.0``).

    Numbers are written with ``repr`` precision and the evaluation settings in a
    ``% fuzzyservo:`` comment, so :func:`parse_fis` gives back an equal system; ``law``
    (:func:`law_text`) in a second one, so a controller's file runs as the controller.
    """
    variables = [*system.inputs, *system.outputs]
    points = max({v.points for v in variables}, key=[v.points for v in variables].count)
    lines = [
        "[System]",
        f"Name={_quoted(system.name, 'system name')}",
        f"Type='{system.type}'",
        f"Version={VERSION}",
        f"NumInputs={len(system.inputs)}",
        f"NumOutputs={len(system.outputs)}",
        f"NumRules={len(system.rules)}",
    ]
    lines += [f"{key}='{getattr(system, attr)}'" for key, (attr, _) in _METHODS.items()]
    lines.append(
        f"{_TAG} semantics={system.semantics} sample_points={system.sample_points} points={points}"
    )
    if law:
        lines.append(f"{_TAG} {law}")
    lines.append("")
    for k, var in enumerate(system.inputs, start=1):
        lines += _variable_text(f"Input{k}", var, points)
    for k, var in enumerate(system.outputs, start=1):
        lines += _variable_text(f"Output{k}", var, points)
    lines.append("[Rules]")
    for rule in system.rules:
        ante = " ".join(str(to_matlab(i)) for i in rule.antecedent)
        cons = " ".join(str(to_matlab(i)) for i in rule.consequents)
        conn = 1 if rule.connective == "and" else 2
        lines.append(f"{ante}, {cons} ({number_text(rule.weight)}) : {conn}")
    return "\n".join(lines) + "\n"
