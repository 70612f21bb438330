"""Calibration on data with an undeclared effect in it (issue 5).

Each test generates a run with the project's own model and one or two effects switched
on, adds measurement noise, writes it as CSV like a logger would, and hands
``fuzzyservo calibrate`` the nominal rig file, which does not declare the effect. The
decision only sees the CSV and the rig.

Effect sizes are in the ranges of MODELLING.md "Typical ranges" (seed 002: stall force
pa·S3 = 4.9 kN, rated current 30 mA):
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from support import DATA, controller_named, rig_named

from fuzzyservo.calibration.synthetic import synthetic_run
from fuzzyservo.cli import main
from fuzzyservo.io.measured import write_measured
from fuzzyservo.io.rigs import load_rig

# Seed 002 rig, P K=10, `pulses`: effect -> parameters (SI) and why they are realistic.
DINCA_EFFECTS = {
    "coulomb_friction": {"force": 300.0},  # 6 % of stall force (1-10 %)
    "stribeck_friction": {  # Fs/Fc = 1.5, vs = 5 mm/s (1.1-1.5; 1-10 mm/s)
        "coulomb_force": 200.0,
        "stiction_force": 100.0,
        "stribeck_velocity": 5e-3,
    },
    "line_resistance": {"resistance": 2e10},  # 128·μ·L/(π·d⁴): 4 m of 4 mm line, μ 0.03 Pa·s
    "internal_leakage": {"coefficient": 1e-12},  # top of 1e-14..1e-12 for cylinders
    "valve_deadband": {"width": 0.5e-3},  # 1.7 % of rated current
    "valve_bias": {"offset": 0.5e-3},  # 1.7 % of rated current (≤ 2-3 %)
    "valve_lag": {"time_constant": 3e-3},  # 53 Hz spool bandwidth (50-200 Hz)
    "transport_delay": {"delay": 0.015},  # 1.5 samples of the 100 Hz loop
    "bulk_modulus": {"effective": 0.6e9},  # hoses or entrained air (0.2-0.7 GPa)
    "supply_droop": {"pump_flow": 1.0e-4},  # a 6 l/min pump; the valve asks up to 11
}
# Acquisition like the seed's: 100 Hz (the loop's own rate), a position transducer
# with 5 µm and pressure transducers with 0.05 bar of white noise.
# (seed 002's p1..p4: the valve's supply and return chambers, the cylinder's two)
PRESSURES = ("p_s", "p_t", "p_a", "p_b")
NOISE = {"y": 5e-6, **dict.fromkeys(PRESSURES, 0.05e5)}
HEADER_UNITS = {"ref": "cm", "i": "mA", "y": "cm", **dict.fromkeys(PRESSURES, "bar")}


def old_loop(folder: Path, rig: str = "dinca_cylinder") -> Path:
    """The seed-002 rig file (or another, ``rig``) as these tests were measured
    on it (before issue 11): no I/O
    delay, an exact reading, ±30 mA, no spool lag (the shipped file declares one, and
    ``valve_lag`` is one of the effects these tests hide in the data). The 20 ms delay
    leaves the P loop less damped, and the closed-loop replays from the data's noisy
    initial state then part from the data by more than the noise floor (declared cost
    2.8 against 1.2); these tests pin the calibration method, not the loop."""
    data = yaml.safe_load((DATA / "rigs" / f"{rig}.yaml").read_text(encoding="utf-8"))
    data.pop("effects", None)
    del data["controller"]["io_delay"]
    for key in ("noise", "adc_bits", "adc_lower", "adc_upper"):
        del data["feedback"][key]
    data["actuator"]["lower"] = {"value": -30, "unit": "mA", "source": "before issue 11"}
    data["actuator"]["upper"] = {"value": 30, "unit": "mA", "source": "before issue 11"}
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{rig}_old_loop.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def dinca_csv(path: Path, effects: dict, seed: int = 7) -> Path:
    """A seed-002 P K=10 `pulses` run with ``effects`` on, as a logged CSV (on the
    :func:`old_loop` rig file beside it)."""
    rig = load_rig(old_loop(path.parent))
    data = synthetic_run(rig, controller_named("p_k10"), "pulses", effects, NOISE, seed=seed)
    return write_measured(path, data, HEADER_UNITS)


def motor_csv(path: Path, effects: dict, seed: int = 3) -> Path:
    """A seed-000 EHS 160 P Kb=0.105 `steps` run at 1 kHz: tachometer speed ±0.2 rad/s,
    port pressures ±0.05 bar."""
    noise = {"w": 0.2, "p_a": 0.05e5, "p_b": 0.05e5}
    data = synthetic_run(
        rig_named("ehs160_motor"), controller_named("p_kb0105"), "steps", effects, noise, seed=seed
    )
    return write_measured(path, data, {"ref": "rad_s", "w": "rad_s", "p_a": "bar", "p_b": "bar"})


def calibrate_json(tmp_path: Path, rig: str, data: Path, controller: str) -> dict:
    out = tmp_path / "out"
    summary = tmp_path / "summary.json"
    code = main(
        [
            "calibrate",
            rig,
            str(data),
            "--controller",
            controller,
            "--out",
            str(out),
            "--json",
            str(summary),
        ]
    )
    assert code == 0
    return json.loads(summary.read_text())


def _names(summary: dict) -> list[str]:
    return [e["name"] for e in summary["effects_added"]]


@pytest.mark.slow
@pytest.mark.parametrize("effect", list(DINCA_EFFECTS))
def test_dinca_names_the_undeclared_effect_first(tmp_path: Path, effect: str) -> None:
    data = dinca_csv(tmp_path / f"{effect}.csv", {effect: DINCA_EFFECTS[effect]})
    summary = calibrate_json(tmp_path, str(old_loop(tmp_path)), data, "p_k10")
    if effect == "coulomb_friction" and _names(summary)[:1] == ["stribeck_friction"]:
        # Issue 12: the held-out test may prefer Stribeck friction with a stiction near 0,
        # the same law, when the one-parameter fit lands 0.2 N off its optimum (stick
        # positions make the closed loop's cost rough). It must carry the true level.
        params = summary["effects_added"][0]["params"]
        assert params["coulomb_force"] == pytest.approx(300.0, rel=0.02)
        assert params["stiction_force"] < 0.01 * 300.0
        return
    if effect == "stribeck_friction":
        _assert_the_stribeck_law(summary)
        if _names(summary)[:2] == ["coulomb_friction", "stribeck_friction"]:
            return
    assert summary["candidates"][0]["name"] == effect
    assert _names(summary)[:1] == [effect]
    before, after = summary["fit_before_pct"], summary["fit_after_pct"]
    for channel in ("y", *PRESSURES):
        assert after[channel] > before[channel], (channel, before, after)
    # the calibrated rig file declares it with the fitted values, and runs
    rig = load_rig(summary["calibrated_rig"])
    assert effect in rig.effects
    true = DINCA_EFFECTS[effect]
    if len(true) == 1:  # one parameter: it is identifiable on its own
        (key, value), fitted = next(iter(true.items())), summary["effects_added"][0]["params"]
        assert fitted[key] == pytest.approx(value, rel=0.2)  # leakage is the weakest: -11 %
        assert rig.effect_values(effect)[key] == pytest.approx(fitted[key])
    code = main(["simulate", summary["calibrated_rig"], "p_k10", "--out", str(tmp_path / "sim")])
    assert code == 0


def _assert_the_stribeck_law(summary: dict) -> None:
    """Friction with stiction at the hidden levels (200 N running, 300 N at breakaway),
    named either as ``stribeck_friction``, or as ``coulomb_friction`` and then
    ``stribeck_friction`` with a running level near 0: the same law in two rounds (the
    plant adds the two Coulomb levels). Which of the two a run gives depends on the last
    bits of the record and of its replays (a stick-slip record: where the piston sticks
    moves with them), so it may differ between CPUs. Over twenty runs (the record's
    stiction force changed by 1-4 ULP, or glibc's exp/pow/tanh without FMA; ten of them
    with loop coefficients a ULP off, as OpenBLAS gave them) eighteen named Stribeck's law
    (running 201-207 N, breakaway 283-296 N) and two, both with the coefficients a ULP off,
    Coulomb's first (running 209-210 N, breakaway 335 N). Held to 10 % on the
    running level and 20 % at breakaway, which a law without stiction (breakaway =
    running, -33 %) fails. The Stribeck velocity trades off against the stiction force
    and is not checked."""
    params = {e["name"]: e["params"] for e in summary["effects_added"]}
    assert "stribeck_friction" in params, _names(summary)
    assert _names(summary)[0] in ("stribeck_friction", "coulomb_friction"), _names(summary)
    stribeck = params["stribeck_friction"]
    running = stribeck["coulomb_force"] + params.get("coulomb_friction", {}).get("force", 0.0)
    assert running == pytest.approx(200.0, rel=0.1)
    assert running + stribeck["stiction_force"] == pytest.approx(300.0, rel=0.2)


@pytest.mark.slow
def test_dinca_without_an_effect_is_none(tmp_path: Path) -> None:
    data = dinca_csv(tmp_path / "none.csv", {})
    summary = calibrate_json(tmp_path, str(old_loop(tmp_path)), data, "p_k10")
    assert summary["effects_added"] == []
    assert summary["decision"] == "none"
    # the nominal model already sits on the noise floor: fit is what noise allows
    assert summary["cost_val"]["declared"] < 1.2


@pytest.mark.slow
def test_dinca_two_effects_are_both_found(tmp_path: Path) -> None:
    effects = {
        "coulomb_friction": DINCA_EFFECTS["coulomb_friction"],
        "valve_lag": DINCA_EFFECTS["valve_lag"],
    }
    data = dinca_csv(tmp_path / "two.csv", effects)
    summary = calibrate_json(tmp_path, str(old_loop(tmp_path)), data, "p_k10")
    assert sorted(_names(summary)) == sorted(effects)
    fitted = {e["name"]: e["params"] for e in summary["effects_added"]}
    assert fitted["coulomb_friction"]["force"] == pytest.approx(300.0, rel=0.05)
    assert fitted["valve_lag"]["time_constant"] == pytest.approx(3e-3, rel=0.1)


# (internal_leakage is not among them: the composed seed-000 rig declares the seed's L_e
# as that effect, rigs/ehs160_motor.yaml, so it is no undeclared effect of this rig)
MOTOR_EFFECTS = {
    "coulomb_friction": {"force": 0.3},  # 6 % of the 5 N·m stall torque, on top of T_f
    "valve_lag": {"time_constant": 5e-3},  # a slower spool than Table 2's 2.3 ms
}


@pytest.mark.slow
@pytest.mark.parametrize("effect", list(MOTOR_EFFECTS))
def test_ehs160_names_the_undeclared_effect_first(tmp_path: Path, effect: str) -> None:
    data = motor_csv(tmp_path / f"{effect}.csv", {effect: MOTOR_EFFECTS[effect]})
    summary = calibrate_json(tmp_path, "ehs160_motor", data, "p_kb0105")
    assert summary["candidates"][0]["name"] == effect
    assert _names(summary)[:1] == [effect]
    for channel in ("w", "p_a", "p_b"):
        assert summary["fit_after_pct"][channel] > summary["fit_before_pct"][channel]


# ---------------------------------------------------------------- bad input, exit 2


def test_closed_loop_replay_without_ref_is_one_line(tmp_path: Path, capsys) -> None:
    data = tmp_path / "noref.csv"
    data.write_text("t_s,y_cm\n" + "".join(f"{k * 0.01},{0.0}\n" for k in range(50)))
    code = main(["calibrate", "dinca_cylinder", str(data), "--controller", "p_k10"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "ref" in err[0] and "noref.csv" in err[0]


def test_unknown_effect_option_is_one_line(tmp_path: Path, capsys) -> None:
    data = dinca_csv(tmp_path / "d.csv", {})
    code = main(["calibrate", "dinca_cylinder", str(data), "--effects", "coulomb,valve_lag"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "coulomb" in err[0]
