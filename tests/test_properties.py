"""Property tests of the loaders: whatever a file holds, a loader returns a valid object or
raises a FuzzyservoError (one line), never anything else. Shipped files are mutated at a
random key with a random value; CSV files and .fis files are generated or mutated.
The budget is small (a few dozen examples each), so the suite stays quick."""

from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

import pytest
import yaml
from support import TESTS, shipped

from fuzzyservo.errors import FuzzyservoError

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

BUDGET = settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,  # the same examples every run: a failure is reproducible
)

WEIRD = st.one_of(
    st.sampled_from(
        [None, True, 0, -1, 1, 1e308, -1e-320, 5e-324, float("nan"), float("inf"), "", "x",
         "../../x", "/abs/x", "70 bar", [], {}, [1, 2], [3, -3], {"value": 1e300, "unit": "min"},
         {"value": "a"}, {"unit": "bar"}, {"value": 1, "unit": "furlong"}, 2**70, "a/b"]
    ),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**6), max_value=10**6),
    st.text(max_size=8),
)  # fmt: skip


def _paths(node, prefix=()):
    """Every key path of a nested mapping (and list index), mapping nodes included."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield (*prefix, key)
            yield from _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield (*prefix, i)
            yield from _paths(value, (*prefix, i))


def _mutate(data: dict, path: tuple, value, action: str) -> dict:
    node = data
    for key in path[:-1]:
        node = node[key]
    last = path[-1]
    if action == "delete" and isinstance(node, dict):
        del node[last]
    elif action == "unknown" and isinstance(node, dict):
        node[f"{last}_typo"] = value
    else:
        node[last] = value
    return data


def _check_loader(load, text: str, suffix: str = ".yaml"):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"file{suffix}"
        path.write_text(text, encoding="utf-8")
        try:
            return load(path)
        except FuzzyservoError as exc:
            assert "\n" not in str(exc)
            return None


def yaml_mutations(data: dict):
    paths = list(_paths(data))
    return st.tuples(st.sampled_from(paths), WEIRD, st.sampled_from(["set", "delete", "unknown"]))


def _dump(data) -> str:
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)


RIG = yaml.safe_load(shipped("dinca_cylinder").read_text())


@BUDGET
@given(yaml_mutations(RIG))
def test_rig_loader_gives_a_rig_or_one_line(mutation):
    import copy

    from fuzzyservo.io.rigs import load_rig
    from fuzzyservo.rig import Rig

    rig = _check_loader(load_rig, _dump(_mutate(copy.deepcopy(RIG), *mutation)))
    assert rig is None or isinstance(rig, Rig)


def _study_data() -> dict:
    data = yaml.safe_load(shipped("dinca_flc", "studies").read_text())
    data["rig"] = str(shipped("dinca_cylinder"))
    for key in ("controller", "baseline"):
        data[key] = str(shipped(Path(data[key]).stem, "studies/controllers"))
    return data


STUDY = _study_data()


@BUDGET
@given(yaml_mutations(STUDY))
def test_study_loader_gives_a_study_or_one_line(mutation):
    import copy

    from fuzzyservo.io.studies import load_study
    from fuzzyservo.tuning.spec import Study

    spec = _check_loader(load_study, _dump(_mutate(copy.deepcopy(STUDY), *mutation)))
    assert spec is None or isinstance(spec, Study)


CONTROLLERS = {
    name: yaml.safe_load(shipped(name, "studies/controllers").read_text())
    for name in ("p_k10", "pi_dinca", "flc2_reshaped", "fpi_ehs160")
}


@BUDGET
@given(st.sampled_from(sorted(CONTROLLERS)).flatmap(
    lambda name: st.tuples(st.just(name), yaml_mutations(CONTROLLERS[name]))))  # fmt: skip
def test_controller_loader_gives_a_controller_or_one_line(named):
    import copy

    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.io.controllers import load_controller

    name, mutation = named
    data = _mutate(copy.deepcopy(CONTROLLERS[name]), *mutation)
    controller = _check_loader(load_controller, _dump(data))
    assert controller is None or isinstance(controller, Controller)


FIS = (TESTS / "data" / "tipper.fis").read_text(encoding="utf-8")
_NUMBER = re.compile(r"-?\d+(\.\d+)?")


@st.composite
def fis_texts(draw):
    lines = FIS.splitlines()
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["number", "delete", "duplicate", "truncate", "garble"]))
        i = draw(st.integers(0, len(lines) - 1))
        if kind == "number" and _NUMBER.search(lines[i]):
            value = draw(st.sampled_from(["-1", "0", "1e308", "nan", "999", "2", "x", ""]))
            lines[i] = _NUMBER.sub(value, lines[i], count=1)
        elif kind == "delete":
            del lines[i]
        elif kind == "duplicate":
            lines.insert(i, lines[i])
        elif kind == "truncate":
            lines[i] = lines[i][: draw(st.integers(0, len(lines[i])))]
        else:
            lines[i] = draw(st.text(max_size=12))
        if not lines:
            break
    return "\n".join(lines) + "\n"


@BUDGET
@given(fis_texts())
def test_fis_loader_gives_a_controller_or_one_line(text):
    from fuzzyservo.controllers.base import Controller
    from fuzzyservo.io.controllers import load_controller

    controller = _check_loader(load_controller, text, suffix=".fis")
    assert controller is None or isinstance(controller, Controller)


HEADERS = ["t_s", "t_ms", "t_min", "y_cm", "y_mm", "y", "i_mA", "p1_bar", "p3_Pa", "u_V",
           "x_furlong", "", "ref_cm", "w_rad_s", "t_V"]  # fmt: skip
CELLS = ["0", "1", "-1", "nan", "", "x", "1e308", "0.01", "2,5", " 3 ", "inf", "1e-320"]


@st.composite
def csv_texts(draw):
    header = draw(st.lists(st.sampled_from(HEADERS), min_size=1, max_size=5))
    rows = draw(st.integers(0, 40))
    regular = draw(st.booleans())
    lines = [",".join(header)]
    for k in range(rows):
        cells = []
        for name in header:
            if regular and name.startswith("t_"):
                cells.append(f"{k * 0.01:.4f}")
            elif regular:
                cells.append(f"{math.sin(k / 3):.5f}")
            else:
                cells.append(draw(st.sampled_from(CELLS)))
        if draw(st.integers(0, 20)) == 0:
            cells = cells[:-1]  # a ragged row now and then
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


@BUDGET
@given(csv_texts())
def test_measured_loader_gives_data_or_one_line(text):
    from fuzzyservo.io.measured import Measured, read_measured

    data = _check_loader(read_measured, text, suffix=".csv")
    assert data is None or (isinstance(data, Measured) and len(data) >= 2)
    if data is not None:
        import numpy as np

        assert np.isfinite(data.t).all() and all(
            np.isfinite(v).all() for v in data.signals.values()
        )


DINCA = None


@BUDGET
@given(csv_texts())
def test_measured_data_against_the_rig_gives_a_replay_or_one_line(text):
    """Readable data checked against the seed-002 rig: a replay or one DataError line."""
    global DINCA
    from support import rig_named

    from fuzzyservo.calibration.replay import make_replay
    from fuzzyservo.io.measured import read_measured

    if DINCA is None:
        DINCA = rig_named("dinca_cylinder")
    data = _check_loader(read_measured, text, suffix=".csv")
    if data is None:
        return
    try:
        make_replay(DINCA, data)
    except FuzzyservoError as exc:
        assert "\n" not in str(exc)
