"""The bad-input audit: every kind of wrong input a new user has given the command line.

Each :class:`Case` is one command line run in a sandbox (a fresh folder: the inputs in
``in/``, the working folder ``work/``). A bad input must give exactly one line on stderr
(``fuzzyservo: error: ...``, naming what ``needs`` lists), exit status 2, no traceback,
and write nothing outside ``work/`` (nor touch a shipped file). Cases with
``expect="ok"`` must instead succeed without writing outside ``work/``.

``tests/test_bad_inputs.py`` runs the table in-process; ``python tests/bad_inputs.py``
runs each case in its own process (time and memory limited) and prints the audit table:
tried / clear error / traceback / silent / unclear / wrote outside.
"""

from __future__ import annotations

import hashlib
import io
import os
import sys
from collections.abc import Callable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from support import TESTS, shipped

Files = dict[str, str | bytes | Callable[[Path], None]]


@dataclass(frozen=True)
class Case:
    id: str
    argv: tuple[str, ...]  # "{in}" is the input folder, "{root}" the sandbox, "{work}" the cwd
    files: Files = field(default_factory=dict)
    needs: tuple[str, ...] = ()  # words the one-line message must contain
    expect: str = "error"  # or "ok": a run that must succeed
    slow: bool = False


# --------------------------------------------------------------------------- file makers
def _text(folder: str, name: str) -> str:
    return shipped(name, folder).read_text(encoding="utf-8")


def _data(folder: str, name: str) -> dict:
    return yaml.safe_load(_text(folder, name))


def _set(data: dict, dotted: str, value) -> dict:
    node = data
    *head, last = dotted.split(".")
    for key in head:
        node = node.setdefault(key, {})
    if value is _DELETE:
        node.pop(last, None)
    else:
        node[last] = value
    return data


_DELETE = object()


def rig(**changes) -> str:
    """dinca_cylinder.yaml with ``changes`` (dotted key with ``__`` for ``.``) applied."""
    data = _data("rigs", "dinca_cylinder")
    for key, value in changes.items():
        _set(data, key.replace("__", "."), value)
    return yaml.safe_dump(data, sort_keys=False)


def controller(base: str = "p_k10", **changes) -> str:
    data = _data("studies/controllers", base)
    for key, value in changes.items():
        _set(data, key.replace("__", "."), value)
    return yaml.safe_dump(data, sort_keys=False)


def study(**changes) -> str:
    """dinca_flc.yaml with its rig and controllers as absolute paths, and ``changes``."""
    data = _data("studies", "dinca_flc")
    data["rig"] = str(shipped("dinca_cylinder"))
    for key in ("controller", "baseline"):
        data[key] = str(shipped(Path(data[key]).stem, "studies/controllers"))
    for key, value in changes.items():
        _set(data, key.replace("__", "."), value)
    return yaml.safe_dump(data, sort_keys=False)


_MEASURED: dict[str, np.ndarray] = {}


def _base_run() -> dict[str, np.ndarray]:
    """A seed-002 P K=10 `steps` run at 100 Hz: t [s], i [mA], ref, y [cm], p_a, p_b [bar]."""
    if not _MEASURED:
        from support import controller_named, rig_named

        from fuzzyservo.calibration.synthetic import synthetic_run

        data = synthetic_run(
            rig_named("dinca_cylinder"),
            controller_named("p_k10"),
            "steps",
            {},
            {"y": 5e-6, "p_a": 5e3, "p_b": 5e3},
            seed=1,
        )
        _MEASURED.update(
            t=data.t,
            i=data.signals["i"] * 1e3,
            ref=data.signals["ref"] * 100,
            y=data.signals["y"] * 100,
            p_a=data.signals["p_a"] / 1e5,
            p_b=data.signals["p_b"] / 1e5,
        )
    return _MEASURED


def measured(
    header: str = "t_s,i_mA,ref_cm,y_cm,p_a_bar,p_b_bar", **edit
) -> Callable[[Path], None]:
    """A CSV of the base run; ``edit`` maps a column (t, i, ref, y, p_a, p_b) to a function
    of its values, or to None to drop it."""

    def make(path: Path) -> None:
        run = dict(_base_run())
        names = header.split(",")
        for key, fn in edit.items():
            if fn is not None:
                run[key] = fn(run[key])
        cols = [c for c, name in zip(run, names, strict=True) if edit.get(c, 1) is not None]
        head = [n for c, n in zip(run, names, strict=True) if edit.get(c, 1) is not None]
        rows = np.column_stack([run[c] for c in cols])
        lines = [",".join(head)] + [",".join(f"{v:.9g}" for v in r) for r in rows]
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")

    return make


def measured_text(transform: Callable[[list[str]], list[str]]) -> Callable[[Path], None]:
    """The base CSV with its lines passed through ``transform``."""

    def make(path: Path) -> None:
        measured()(path)
        lines = path.read_text(encoding="utf-8").splitlines()
        path.write_text("\n".join(transform(lines)) + "\n", encoding="utf-8")

    return make


def valve_csv(rows: int = 120, header: str = "p_s_bar,u_c_V,p_a_bar,p_b_bar,q_a_l_min,q_b_l_min"):
    def make(path: Path) -> None:
        rng = np.random.default_rng(0)
        lines = [header]
        for _ in range(rows):
            ps = rng.uniform(9, 31)
            u = rng.uniform(-6, 6)
            pa, pb = rng.uniform(0, ps, 2)
            lines.append(f"{ps:.4f},{u:.4f},{pa:.4f},{pb:.4f},{u * 2:.4f},{-u * 2:.4f}")
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")

    return make


def alias_bomb(levels: int) -> str:
    """A YAML flow value of ``levels`` anchors, each nine aliases of the one before: a
    "billion laughs" (9**levels strings once expanded) in a few hundred bytes."""
    items = ['&a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    items += [f"&a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, levels)]
    return f"[{', '.join(items)}]"


def nested(depth: int) -> str:
    """A YAML flow value nested ``depth`` lists deep."""
    return "[" * depth + "]" * depth


def with_value(text: str, line: str, value: str) -> str:
    """``text`` with the line ``line`` (``key: value``) given ``value`` instead."""
    key = line.split(":")[0]
    return _replace(f"\n{line}\n", f"\n{key}: {value}\n", "\n" + text)[1:]


def _replace(old: str, new: str, text: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


# --------------------------------------------------------------------------- the table
SIM = ("simulate", "{in}/rig.yaml", "p_k10", "--out", "{work}/out")
SIMC = ("simulate", "dinca_cylinder", "{in}/c.yaml", "--scenario", "steps", "--out", "{work}/out")
TUNE = ("tune", "{in}/s.yaml", "--trials", "1", "--out", "{work}/out/s")
CAL = ("calibrate", "dinca_cylinder", "{in}/d.csv", "--max-effects", "0", "--out", "{work}/out/c")
STEPS = ("--scenario", "steps")
DINCA = "dinca_cylinder"


def _cases() -> list[Case]:
    c: list[Case] = []
    add = c.append
    sim = ("simulate", DINCA, "p_k10", *STEPS, "--out", "{work}/out")
    # -- command-line values -----------------------------------------------------------
    for value in ("-5", "0", "nan", "inf", "1e9", "1e-12", "abc"):
        add(Case(f"cli --duration {value}", (*sim, "--duration", value), needs=("--duration",)))
    add(Case("cli --scenario unknown", (*sim[:3], "--scenario", "nope"), needs=("nope",)))
    add(Case("cli unknown rig name", ("simulate", "nosuchrig", "p_k10"), needs=("nosuchrig",)))
    add(Case("cli unknown controller", ("simulate", DINCA, "nosuch"), needs=("nosuch",)))
    add(Case("cli missing rig path", ("simulate", "x/y.yaml", "p_k10"), needs=("x/y.yaml",)))
    add(Case("cli rig path is a folder", ("simulate", "{in}", "p_k10"), needs=("{in}",)))
    exist = {"taken": "a file, not a folder\n"}
    add(Case("cli simulate --out existing file", (*sim[:-1], "{in}/taken"), exist, ("--out",)))
    add(
        Case(
            "cli compare --out existing file",
            ("compare", DINCA, "p_k10", *STEPS, "--out", "{in}/taken"),
            exist,
            ("--out",),
        )
    )
    add(
        Case(
            "cli show --out existing file",
            ("show", "flc1_translated", "--out", "{in}/taken"),
            exist,
            ("--out",),
        )
    )
    add(
        Case(
            "cli tune --out existing file",
            ("tune", "dinca_flc", "--trials", "1", "--out", "{in}/taken"),
            exist,
            ("--out",),
        )
    )
    add(
        Case(
            "cli calibrate --out existing file",
            (*CAL[:-1], "{in}/taken"),
            {"d.csv": measured(), **exist},
            ("--out",),
        )
    )
    add(Case("cli --json is a folder", (*sim, "--json", "{in}"), needs=("--json",)))
    add(
        Case(
            "cli --json in a missing folder is created",
            (*sim, "--json", "{work}/j/x.json"),
            expect="ok",
        )
    )
    add(
        Case(
            "cli compare duplicate names",
            ("compare", DINCA, "p_k10", "p_k10", *STEPS),
            needs=("name",),
        )
    )
    for value in ("0", "-3"):
        add(Case(f"cli tune --trials {value}", ("tune", "--trials", value), needs=("--trials",)))
    add(Case("cli tune --workers 0", ("tune", "--workers", "0"), needs=("--workers",)))
    tune1 = ("tune", "dinca_flc", "--trials", "1", "--out", "{work}/out/t")
    for label, url in (
        ("unreachable postgresql", "postgresql://nobody@127.0.0.1:9/nodb"),
        ("mysql", "mysql://user@localhost/db"),
        ("garbage", "not a url"),
        ("sqlite in a missing folder", "sqlite:///{root}/nodir/x.db"),
    ):
        add(Case(f"cli tune --storage {label}", (*tune1, "--storage", url), needs=("--storage",)))
    add(Case("cli tune unknown study", ("tune", "nosuchstudy"), needs=("nosuchstudy",)))
    add(Case("cli bench unknown case", ("bench", "--case", "nope"), needs=("nope",)))
    for opt in ("--runs", "--reference-runs", "--study-trials", "--workers"):
        add(Case(f"cli bench {opt} 0", ("bench", "--case", "fuzzy_eval", opt, "0"), needs=(opt,)))
    for opt in ("--max-effects", "--bootstrap-draws"):
        add(Case(f"cli calibrate {opt} -1", (*CAL[:3], opt, "-1"), {"d.csv": measured()}, (opt,)))
    add(
        Case(
            "cli calibrate --effects unknown",
            (*CAL, "--effects", "nope"),
            {"d.csv": measured()},
            ("--effects: unknown effect 'nope'",),
        )
    )
    add(
        Case(
            "cli calibrate missing data", ("calibrate", DINCA, "{in}/none.csv"), needs=("none.csv",)
        )
    )
    add(
        Case(
            "cli calibrate controller unknown",
            (*CAL, "--controller", "nosuch"),
            {"d.csv": measured()},
            ("nosuch",),
        )
    )
    fit = ("fit-valve", "{in}/v.csv", "--restarts", "1")
    add(
        Case(
            "cli fit-valve --restarts 0",
            ("fit-valve", "{in}/v.csv", "--restarts", "0"),
            {"v.csv": valve_csv()},
            ("--restarts",),
        )
    )
    add(Case("cli fit-valve missing data", ("fit-valve", "{in}/none.csv"), needs=("none.csv",)))
    add(
        Case(
            "cli fit-valve default keeps the shipped network",
            fit,
            {"v.csv": valve_csv()},
            expect="ok",
        )
    )
    add(
        Case(
            "cli fit-valve --out is a folder",
            (*fit, "--out", "{in}"),
            {"v.csv": valve_csv()},
            ("--out",),
        )
    )
    add(
        Case(
            "cli fit-valve unknown rig",
            (*fit, "--rig", "nosuch"),
            {"v.csv": valve_csv()},
            ("nosuch",),
        )
    )
    add(
        Case(
            "cli export a P controller",
            ("export", "p_k10", "--fis", "{work}/x.fis"),
            needs=("fuzzy",),
        )
    )
    add(
        Case(
            "cli export a rig as C",
            ("export", "dinca_cylinder", "--c", "{work}/c"),
            needs=("dinca_cylinder", "--fmu"),
        )
    )
    add(
        Case(
            "cli export a rig's plant to a file not ending in .fmu",
            ("export", "dinca_cylinder", "--fmu", "{work}/plant.zip"),
            needs=("--fmu", ".fmu"),
        )
    )
    add(Case("cli show a P controller", ("show", "p_k10", "--out", "{work}/o"), needs=("fuzzy",)))
    add(
        Case(
            "cli export --fis is a folder",
            ("export", "flc1_translated", "--fis", "{in}"),
            needs=("--fis",),
        )
    )
    for lut, controller_name, most in (
        ("1000000000", "fpi_ehs160", "256"),
        ("65537", "flc1_translated", "65,536"),
    ):
        add(
            Case(
                f"cli export --lut {lut} ({controller_name})",
                ("export", controller_name, "--c", "{work}/c", "--lut", lut),
                needs=("--lut", most),
            )
        )
    add(
        Case(
            "cli robustness --samples 1e9",
            ("robustness", DINCA, "p_k10", "--samples", "1000000000"),
            needs=("--samples", "100,000"),
        )
    )
    add(
        Case(
            "cli tune --check-samples 1e9",
            ("tune", "dinca_robust", "--check-samples", "1000000000", "--trials", "1"),
            needs=("--check-samples", "100,000"),
        )
    )
    add(Case("cli unknown option", ("simulate", DINCA, "p_k10", "--bogus"), needs=("--bogus",)))
    add(Case("cli --trials not a number", ("tune", "--trials", "many"), needs=("--trials",)))

    # -- rig files -------------------------------------------------------------------------
    base = _text("rigs", "dinca_cylinder")
    sup, cyl = (
        "plant__components__supply__parameters__",
        "plant__components__cylinder__parameters__",
    )
    oil = "plant__components__oil__parameters__"
    rigs: list[tuple[str, str, tuple[str, ...]]] = [
        ("duplicate top-level key", base + "\nname: other\n", ("name", "twice")),
        (
            "duplicate parameter key",
            _replace(
                "        piston_mass:",
                "        rod_diameter: {value: 7, unit: mm}\n        piston_mass:",
                base,
            ),
            ("rod_diameter", "twice"),
        ),
        (
            "duplicate scenario",
            _replace("  steps:\n", "  pulses:\n    duration: 1\n  steps:\n", base),
            ("pulses",),
        ),
        (
            "supply pressure 70 (Pa, no unit)",
            rig(**{sup + "supply_pressure": 70}),
            ("supply_pressure", "bar"),
        ),
        (
            "supply pressure 70 Pa",
            rig(**{sup + "supply_pressure": {"value": 70, "unit": "Pa"}}),
            ("supply_pressure",),
        ),
        (
            "initial position beyond the stroke",
            rig(plant__initial__position={"value": 20, "unit": "cm"}),
            ("position", "stroke"),
        ),
        (
            "initial position before the stroke",
            rig(plant__initial__position={"value": -5, "unit": "cm"}),
            ("position", "stroke"),
        ),
        (
            "scenario initial position beyond the stroke",
            rig(scenarios__steps__initial={"position": {"value": 1, "unit": "m"}}),
            ("position", "stroke"),
        ),
        ("name with a slash", rig(name="a/b"), ("name",)),
        ("name with an absolute path", rig(name="{root}/abs/x"), ("name",)),
        ("name climbing out", rig(name="../../x"), ("name",)),
        ("empty name", rig(name=""), ("name",)),
        ("name '..'", rig(name=".."), ("name",)),
        (
            "scenario name with a path",
            rig(**{"scenarios__../../evil": _data("rigs", DINCA)["scenarios"]["steps"]}),
            ("scenarios",),
        ),
        (
            "duration 1e7 s",
            rig(scenarios__pulses__duration={"value": 1e7, "unit": "s"}),
            ("duration",),
        ),
        (
            "duration 1e307 min",
            rig(scenarios__pulses__duration={"value": 1e307, "unit": "min"}),
            ("duration",),
        ),
        (
            "sample time subnormal",
            rig(controller__sample_time={"value": 1e-310, "unit": "s"}),
            ("sample_time",),
        ),
        ("sample time bare subnormal", rig(controller__sample_time=5e-324), ("sample_time",)),
        (
            "sample time 1e307 min",
            rig(controller__sample_time={"value": 1e307, "unit": "min"}),
            ("sample_time",),
        ),
        (
            "bulk modulus 1e307 kbar",
            rig(**{oil + "bulk_modulus": {"value": 1e307, "unit": "kbar"}}),
            ("bulk_modulus",),
        ),
        (
            "unknown unit",
            rig(**{cyl + "piston_mass": {"value": 1, "unit": "furlong"}}),
            ("piston_mass",),
        ),
        (
            "wrong kind of unit",
            rig(**{cyl + "piston_mass": {"value": 1, "unit": "bar"}}),
            ("piston_mass",),
        ),
        ("unknown key", rig(**{cyl + "pistn_mass": 1}), ("pistn_mass",)),
        ("unknown plant type", rig(plant__type="nope"), ("type",)),
        ("YAML syntax error", base + "\n  : : [\n", ("YAML",)),
        ("top level is a list", "- a\n- b\n", ("mapping",)),
        ("empty file", "", ("mapping",)),
        ("value as text with a unit", rig(**{cyl + "piston_mass": "1 kg"}), ("piston_mass",)),
        (
            "value .nan",
            base.replace("piston_mass: {value: 1,", "piston_mass: {value: .nan,"),
            ("piston_mass",),
        ),
        (
            "value .inf",
            base.replace("piston_mass: {value: 1,", "piston_mass: {value: .inf,"),
            ("piston_mass",),
        ),
        (
            "negative bulk modulus",
            rig(**{oil + "bulk_modulus": {"value": -1, "unit": "bar"}}),
            ("bulk_modulus",),
        ),
        ("feedback gain zero", rig(feedback__gain={"value": 0, "unit": "V/cm"}), ("gain",)),
        (
            "actuator lower above upper",
            rig(actuator__lower={"value": 40, "unit": "mA"}),
            ("lower",),
        ),
        ("unknown output signal", rig(output__signal="z"), ("signal",)),
        ("unknown reference type", rig(scenarios__pulses__reference={"type": "ramp"}), ("type",)),
        (
            "warm-up longer than duration",
            rig(scenarios__pulses__warmup={"value": 30, "unit": "s"}),
            ("warmup",),
        ),
        ("pulse period zero", rig(scenarios__pulses__reference__period_s=0), ("period_s",)),
        (
            "steps values and times differ",
            rig(scenarios__steps__reference__values=[1.0]),
            ("steps",),
        ),
        ("no scenarios", rig(scenarios={}), ("scenarios",)),
        ("unknown effect", rig(effects={"magic": {}}), ("magic",)),
        (
            "effect parameter in a wrong unit",
            rig(effects={"coulomb_friction": {"force": {"value": 1, "unit": "bar"}}}),
            ("force",),
        ),
        (
            "measured sample period subnormal",
            rig(measured={"sample_period": {"value": 1e-310, "unit": "s"}}),
            ("sample_period",),
        ),
        ("YAML alias", "a: &x [1]\nb: *x\n" + base, ("a",)),
        (
            "YAML alias bomb",
            with_value(base, "name: dinca_cylinder", alias_bomb(9)),
            ("line 8", "aliases", "10,000"),
        ),
        (
            "YAML nested 20,000 deep",
            with_value(base, "name: dinca_cylinder", nested(20_000)),
            ("line 8", "deeper than 100"),
        ),
        (
            "unit of 100,000 characters",
            rig(**{cyl + "piston_mass": {"value": 1, "unit": "(" * 50_000 + "kg" + ")" * 50_000}}),
            ("piston_mass", "100,002 characters"),
        ),
    ]
    for label, text, needs in rigs:
        add(Case(f"rig {label}", SIM, {"rig.yaml": text}, needs))
    add(Case("rig not UTF-8", SIM, {"rig.yaml": b"name: \xff\xfe\n"}, ("UTF-8",)))
    hp = _data("rigs", "hydroprax_pdcv")
    hp["plant"]["components"]["valve"] = {
        "type": "network_valve",
        "parameters": {
            "control_voltage_max": {"value": 6, "unit": "V"},
            "weights": {"file": "../../nowhere.json"},
        },
    }
    add(
        Case(
            "rig weights file missing",
            ("simulate", "{in}/rig.yaml", "pi_hydroprax"),
            {"rig.yaml": yaml.safe_dump(hp, sort_keys=False)},
            ("weights",),
        )
    )

    # -- controller files ------------------------------------------------------------------
    ctrl = _text("studies/controllers", "p_k10")
    controllers: list[tuple[str, str, tuple[str, ...]]] = [
        ("name with a slash", controller(name="a/b"), ("name",)),
        ("name climbing out", controller(name="../../x"), ("name",)),
        ("name with an absolute path", controller(name="{root}/abs/x"), ("name",)),
        ("duplicate key", ctrl + "gain: 20\n", ("gain", "twice")),
        ("unknown kind", controller(kind="PID"), ("kind",)),
        ("gain as text", controller(gain="ten"), ("gain",)),
        ("gain .nan", ctrl.replace("gain: 10", "gain: .nan"), ("gain",)),
        ("output limits reversed", controller(output_limits=[3, -3]), ("output_limits",)),
        ("output limits 1e400", ctrl.replace("[-10, 10]", "[-1e400, 1e400]"), ("output_limits",)),
        ("PI key in a P file", controller(ki=1), ("ki",)),
        ("fuzzy input not a mapping", controller("flc1_translated", input="wide"), ("input",)),
        (
            "fuzzy duplicate key",
            _text("studies/controllers", "flc1_translated") + "form: pd\n",
            ("form", "twice"),
        ),
        ("fuzzy name with a path", controller("flc1_translated", name="../../evil"), ("name",)),
        ("alias bomb", with_value(ctrl, "gain: 10", alias_bomb(9)), ("line 5", "aliases")),
        ("nested 20,000 deep", with_value(ctrl, "gain: 10", nested(20_000)), ("deeper than 100",)),
        ("gain as 100,000 characters", controller(gain="g" * 100_000), ("gain", "100,000")),
        ("fuzzy points 1e9", controller("flc1_translated", points=10**9), ("points", "5,000")),
        (
            "fuzzy sample_points 1e9",
            controller("flc1_translated", semantics="matlab", sample_points=10**9),
            ("sample_points", "100,000"),
        ),
    ]
    for label, text, needs in controllers:
        add(Case(f"controller {label}", SIMC, {"c.yaml": text}, needs))
    fis = (TESTS / "data" / "tipper.fis").read_text(encoding="utf-8")
    fis_cases = [
        ("name climbing out", fis.replace("Name='tipper'", "Name='../../evil'"), ("Name",)),
        ("garbage", "this is not a fis file\n", ("x.fis",)),
        ("no rules", fis.split("[Rules]")[0], ("Rules",)),
        ("points=1000000000", "% fuzzyservo: points=1000000000\n" + fis, ("points", "5,000")),
        (
            "Range nested 100,000 deep",
            fis.replace("Range=[0 10]", f"Range=[{'(' * 100_000}0{')' * 100_000} 10]", 1),
            ("Range", "200,001 characters"),
        ),
    ]
    add(
        Case(
            "fis Name with a path is not a file name (the file stem is)",
            ("show", "{in}/x.fis", "--out", "{work}/out"),
            {"x.fis": fis.replace("Name='tipper'", "Name='../../evil'")},
            expect="ok",
        )
    )
    for label, text, needs in fis_cases[1:]:
        add(
            Case(
                f"fis {label}",
                ("show", "{in}/x.fis", "--out", "{work}/out"),
                {"x.fis": text},
                needs,
            )
        )

    # -- study files -----------------------------------------------------------------------
    studies: list[tuple[str, str, tuple[str, ...], tuple[str, ...]]] = [
        ("name climbing out", study(name="../../x"), ("name",), ()),
        ("name climbing out, default --out", study(name="../../x"), ("name",), ("default",)),
        ("name with an absolute path", study(name="{root}/abs/x"), ("name",), ()),
        (
            "SQLite storage outside the output",
            study(storage="sqlite:///{root}/x.db"),
            ("storage",),
            (),
        ),
        ("mysql storage", study(storage="mysql://u@localhost/db"), ("storage",), ()),
        ("duplicate key", study() + "trials: 5\n", ("trials", "twice"), ()),
        ("alias bomb", with_value(study(), "name: dinca_flc", alias_bomb(9)), ("aliases",), ()),
        (
            "nested 20,000 deep",
            with_value(study(), "name: dinca_flc", nested(20_000)),
            ("deeper than 100",),
            (),
        ),
        ("trials 0", study(trials=0), ("trials",), ()),
        ("unknown sampler", study(sampler="grid"), ("sampler",), ()),
        ("no parameters", study(parameters={}), ("parameters",), ()),
        (
            "unknown parameter path",
            study(parameters={"nope.x": {"low": 0, "high": 1}}),
            ("nope.x",),
            (),
        ),
        ("bad constraint", study(constraints=["overshoot_pct << 5"]), ("constraints",), ()),
        ("unknown scenario", study(scenarios=["nope"]), ("nope",), ()),
        ("unknown rig", study(rig="nosuchrig"), ("rig",), ()),
        ("unknown metric", study(objective={"metric": "speed"}), ("speed",), ()),
        (
            "low above high",
            study(parameters={"gains.output": {"low": 2, "high": 1}}),
            ("gains.output",),
            (),
        ),
        (
            "log not true or false",
            study(parameters={"gains.output": {"low": 1, "high": 2, "log": "yes"}}),
            ("gains.output.log", "true or false", "'yes'"),
            (),
        ),
    ]
    for label, text, needs, flags in studies:
        argv = ("tune", "{in}/s.yaml", "--trials", "1") if flags else TUNE
        add(Case(f"study {label}", argv, {"s.yaml": text}, needs))

    # -- measured data ---------------------------------------------------------------------
    data_cases: list[tuple[str, object, tuple[str, ...]]] = [
        ("position in mm under a cm header", measured(y=lambda y: y * 10), ("y_cm", "mm")),
        ("time in ms under an s header", measured(t=lambda t: t * 1000), ("t_s", "ms")),
        ("no y column", measured(y=None), ("y",)),
        ("constant (stuck) position", measured(y=lambda y: y * 0 + 1.0), ("y_cm",)),
        (
            "pressure in bar under a Pa header",
            measured("t_s,i_mA,ref_cm,y_cm,p_a_Pa,p_b_Pa"),
            ("p_a_Pa",),
        ),
        ("empty file", "", ("empty",)),
        ("header only", "t_s,i_mA,y_cm\n", ("rows",)),
        ("text cell", measured_text(lambda ls: [*ls[:5], "0.04,x,1,1,1,1", *ls[6:]]), ("row 6",)),
        ("empty cell", measured_text(lambda ls: [*ls[:5], "0.04,,1,1,1,1", *ls[6:]]), ("row 6",)),
        ("NaN cell", measured_text(lambda ls: [*ls[:5], "0.04,nan,1,1,1,1", *ls[6:]]), ("NaN",)),
        ("time backwards", measured(t=lambda t: t[::-1].copy()), ("backwards",)),
        ("repeated stamps", measured(t=lambda t: np.round(t, 1)), ("repeated", "--resample")),
        ("uneven sampling", measured(t=lambda t: t**1.2), ("uneven", "--resample")),
        ("unknown unit", measured("t_s,i_mA,ref_cm,y_furlong,p_a_bar,p_b_bar"), ("y_furlong",)),
        ("header without unit", measured("t_s,i_mA,ref_cm,y,p_a_bar,p_b_bar"), ("'y'",)),
        ("too few samples", measured_text(lambda ls: ls[:10]), ("samples",)),
        ("ragged row", measured_text(lambda ls: [*ls[:5], "1,2", *ls[6:]]), ("row 6",)),
        ("duplicate column", measured("t_s,i_mA,ref_cm,y_cm,p_a_bar,p_a_bar"), ("p_a_bar",)),
        ("not UTF-8", b"t_s,y_cm\n\xff\xfe\n", ("UTF-8",)),
        ("position in volts", measured("t_s,i_mA,ref_cm,y_V,p_a_bar,p_b_bar"), ("y",)),
        (
            "time 1e307 min",
            measured("t_min,i_mA,ref_cm,y_cm,p_a_bar,p_b_bar", t=lambda t: t * 1e307),
            ("t_min",),
        ),
        (
            "semicolons and decimal commas",
            measured_text(lambda ls: [line.replace(",", ";").replace(".", ",") for line in ls]),
            ("is not a number", "decimal point"),
        ),
    ]
    for label, content, needs in data_cases:
        add(Case(f"data {label}", CAL, {"d.csv": content}, needs))
    add(
        Case(
            "data .mat garbage",
            (*CAL[:2], "{in}/d.mat", *CAL[3:]),
            {"d.mat": b"garbage"},
            ("d.mat",),
        )
    )
    add(Case("data is a folder", (*CAL[:2], "{in}", *CAL[3:]), needs=("{in}",)))
    add(
        Case(
            "data closed loop without ref",
            (*CAL, "--controller", "p_k10"),
            {"d.csv": measured(ref=None)},
            ("ref",),
        )
    )
    valve = [
        ("wrong header", valve_csv(header="a,b,c,d,e,f"), ("header",)),
        (
            "text cell",
            lambda p: valve_csv()(p) or p.write_text(p.read_text() + "1,2,x,4,5,6\n"),
            ("x",),
        ),
        ("empty file", "", ("empty",)),
    ]
    for label, content, needs in valve:
        add(
            Case(
                f"valve data {label}",
                ("fit-valve", "{in}/v.csv", "--out", "{work}/net.json"),
                {"v.csv": content},
                needs,
            )
        )
    return c


CASES = _cases()


# --------------------------------------------------------------------------- running
def _fill(text: str, root: Path) -> str:
    return (
        text.replace("{in}", str(root / "in"))
        .replace("{work}", str(root / "work"))
        .replace("{root}", str(root))
    )


def prepare(case: Case, root: Path) -> list[str]:
    """Make the sandbox ``root`` for ``case``; return the filled-in command line."""
    (root / "in").mkdir(parents=True, exist_ok=True)
    (root / "work").mkdir(exist_ok=True)
    for name, content in case.files.items():
        path = root / "in" / name
        if callable(content):
            content(path)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(_fill(content, root), encoding="utf-8")
    return [_fill(a, root) for a in case.argv]


def snapshot(root: Path) -> dict[str, str]:
    """Every file outside ``root/work`` and every shipped file, with its content hash."""
    data = shipped("dinca_cylinder").parent.parent
    files = {}
    for base in (root, data / "rigs", data / "studies"):
        for path in base.rglob("*"):
            if path.is_file() and (root / "work") not in path.parents:
                files[str(path)] = hashlib.sha1(path.read_bytes()).hexdigest()
    return files


@dataclass
class Outcome:
    code: int | None
    stderr: str
    traceback: bool
    outside: list[str]

    def verdict(self, case: Case, root: Path) -> str:
        if self.outside:
            return "wrote outside"
        if self.traceback:
            return "traceback"
        if case.expect == "ok":
            return "clear" if self.code == 0 else "unclear"
        if self.code in (0, 1):
            return "silent"
        lines = [line for line in self.stderr.splitlines() if line.strip()]
        needs = [_fill(n, root) for n in case.needs]
        if (
            self.code == 2
            and len(lines) == 1
            and "error:" in lines[0]
            and all(n in lines[0] for n in needs)
        ):
            return "clear"
        return "unclear"


def run_inprocess(case: Case, root: Path) -> Outcome:
    """Run ``case`` with :func:`fuzzyservo.cli.main` in this process, cwd ``root/work``."""
    from fuzzyservo.cli import main

    argv = prepare(case, root)
    before = snapshot(root)
    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(root / "work")
    traceback = False
    try:
        with redirect_stderr(err), redirect_stdout(out):
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse
                code = exc.code if isinstance(exc.code, int) else 2
    except Exception:
        import traceback as tb

        err.write(tb.format_exc())
        traceback, code = True, None
    finally:
        os.chdir(cwd)
    after = snapshot(root)
    outside = sorted(k for k, v in after.items() if before.get(k) != v)
    return Outcome(code, err.getvalue(), traceback, outside)


def run_subprocess(case: Case, root: Path, timeout_s: float = 180) -> Outcome:
    """Run ``case`` as ``python -m fuzzyservo`` (4 GB address space, ``timeout_s``)."""
    import resource
    import subprocess

    argv = prepare(case, root)
    before = snapshot(root)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))

    try:
        proc = subprocess.run(
            [sys.executable, "-m", "fuzzyservo", *argv],
            cwd=root / "work",
            capture_output=True,
            text=True,
            timeout=timeout_s,
            preexec_fn=limit,
            stdin=subprocess.DEVNULL,
        )
        code, stderr = proc.returncode, proc.stderr
        traceback = "Traceback" in stderr or code < 0 or code not in (0, 1, 2, 130)
    except subprocess.TimeoutExpired:
        code, stderr, traceback = None, f"(no answer in {timeout_s:.0f} s)", True
    after = snapshot(root)
    outside = sorted(k for k, v in after.items() if before.get(k) != v)
    return Outcome(code, stderr, traceback, outside)


def audit(cases: list[Case], workers: int = 2) -> list[tuple[Case, str, str]]:
    """Run ``cases`` in subprocesses; return (case, verdict, last stderr line)."""
    import shutil
    import tempfile
    from concurrent.futures import ThreadPoolExecutor

    base = Path(tempfile.mkdtemp(prefix="fuzzyservo-audit-"))

    def one(numbered: tuple[int, Case]) -> tuple[Case, str, str]:
        n, case = numbered
        root = base / f"case{n:03d}"
        outcome = run_subprocess(case, root)
        verdict = outcome.verdict(case, root)
        lines = [line for line in outcome.stderr.splitlines() if line.strip()]
        detail = lines[-1] if lines else f"(exit {outcome.code}, nothing on stderr)"
        if outcome.outside:
            detail = f"wrote {outcome.outside[0]}"
        return case, verdict, detail

    with ThreadPoolExecutor(workers) as pool:
        rows = list(pool.map(one, enumerate(cases)))
    shutil.rmtree(base, ignore_errors=True)
    return rows


def main() -> None:
    """Print the audit table (``python tests/bad_inputs.py [substring]``)."""
    wanted = sys.argv[1] if len(sys.argv) > 1 else ""
    rows = audit([c for c in CASES if wanted in c.id])
    kinds = ("clear", "traceback", "silent", "unclear", "wrote outside")
    for case, verdict, detail in rows:
        print(f"{verdict:<13} {case.id:<55} {detail[:160]}")
    print()
    print("| tried | " + " | ".join(kinds) + " |")
    print("|---:|" + "---:|" * len(kinds))
    counts = [sum(v == k for _, v, _ in rows) for k in kinds]
    print(f"| {len(rows)} | " + " | ".join(map(str, counts)) + " |")


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
