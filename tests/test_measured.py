"""Measured-data reader: unit conversions, bad files, mapping, .mat, resampling, splits.

Bad-input cases (STYLE.md practice 9) write a small CSV into ``tmp_path`` and check that
:func:`read_measured` raises one :class:`DataError` line naming the file, the column and
the problem; any other exception type fails the test.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from support import SHARED

from fuzzyservo.errors import DataError
from fuzzyservo.io.measured import Measured, read_measured

N = 50
T = 0.01
FASTER = SHARED / "data" / "faster" / "faster.csv"
FASTER_MAPPING = {"t": "t_s", "r": "ref_1", "u": "u_V", "y": "f_1", "d": "d_mm"}


def write_csv(tmp_path: Path, header: list[str], columns: list[list], name: str = "m.csv") -> Path:
    path = tmp_path / name
    lines = [",".join(header)]
    lines += [",".join(str(c[i]) for c in columns) for i in range(len(columns[0]))]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def good_columns(n: int = N) -> tuple[list[str], list[list]]:
    t = [round(i * T, 6) for i in range(n)]
    return ["t_s", "u_V", "y_cm"], [t, [0.5] * n, [float(i) for i in range(n)]]


def expect_error(path: Path, *hints: str, **kwargs) -> str:
    with pytest.raises(DataError) as info:
        read_measured(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    for hint in hints:
        assert hint in message, f"{hint!r} not in {message!r}"
    return message


# -- conversions ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("header", "value", "si", "unit"),
    [
        ("x_cm", 12.5, 0.125, "m"),
        ("p1_bar", 70.0, 7.0e6, "Pa"),
        ("i_mA", 20.0, 0.020, "A"),
        ("w_rpm", 60.0, 2.0 * math.pi, "rad/s"),
        ("theta_deg", 180.0, math.pi, "rad"),
        ("w_rad_s", 3.0, 3.0, "rad/s"),
        ("v_m_s", 0.2, 0.2, "m/s"),
        ("tau_N_m", 4.0, 4.0, "N*m"),
        ("p2_kPa", 5.0, 5.0e3, "Pa"),
        ("d_mm", 3.0, 3.0e-3, "m"),
        ("ref_1", 0.7, 0.7, "1"),
    ],
)
def test_conversion_to_si(tmp_path, header, value, si, unit):
    names, cols = good_columns()
    path = write_csv(tmp_path, [*names, header], [*cols, [value] * N])
    data = read_measured(path)
    signal = header[: header.index("_")]
    assert data.units[signal] == unit
    np.testing.assert_allclose(data.signals[signal], si, rtol=1e-12)
    np.testing.assert_allclose(data.signals["y"], np.arange(N) * 1e-2)  # cm -> m


def test_time_in_ms_and_sample_period(tmp_path):
    path = write_csv(
        tmp_path, ["t_ms", "u_V", "y_m"], [[i * 2 for i in range(N)], [0] * N, [1] * N]
    )
    data = read_measured(path)
    assert data.t[-1] == pytest.approx((N - 1) * 2e-3)
    assert data.sample_period_s == pytest.approx(2e-3)
    assert "t" not in data.signals and data.source == str(path)


def test_measured_is_frozen(tmp_path):
    names, cols = good_columns()
    data = read_measured(write_csv(tmp_path, names, cols))
    with pytest.raises(AttributeError):
        data.source = "x"  # type: ignore[misc]
    with pytest.raises(ValueError):
        data.signals["y"][0] = 1.0


# -- bad files -----------------------------------------------------------------------------


def test_unknown_unit(tmp_path):
    names, cols = good_columns()
    path = write_csv(tmp_path, [*names, "y2_furlong"], [*cols, [1] * N])
    expect_error(path, "'y2_furlong'", "unknown unit 'furlong'", "bar")


def test_header_without_unit(tmp_path):
    names, cols = good_columns()
    path = write_csv(tmp_path, [*names, "pressure"], [*cols, [1] * N])
    expect_error(path, "'pressure'", "no unit", "measured: columns")


def test_time_in_wrong_unit(tmp_path):
    path = write_csv(tmp_path, ["t_N_m", "u_V"], [[1] * N, [1] * N])
    expect_error(path, "'t_N_m'", "not a time unit", "tau_N_m")


def test_missing_required_signal(tmp_path):
    names, cols = good_columns()
    path = write_csv(tmp_path, names[:2], cols[:2])
    expect_error(path, "required signal 'y' missing", "y_<unit>", require=("t", "u", "y"))


def test_missing_time(tmp_path):
    path = write_csv(tmp_path, ["u_V", "y_m"], [[1] * N, [2] * N])
    expect_error(path, "no time column", "measured: sample_period")
    assert len(read_measured(path, sample_period_s=T)) == N


@pytest.mark.parametrize(
    ("t_values", "hints"),
    [
        ([0.0, 0.01, 0.01, *[0.01 * i for i in range(3, N)]], ("repeated time stamp", "row 4")),
        ([0.0, 0.02, 0.01, *[0.01 * i for i in range(3, N)]], ("time goes backwards", "row 4")),
        ([0.01 * i for i in range(N - 1)] + [0.6], ("uneven sampling", "worst gap", "row 50")),
    ],
    ids=["duplicate", "backwards", "uneven"],
)
def test_bad_time(tmp_path, t_values, hints):
    names, cols = good_columns()
    path = write_csv(tmp_path, names, [t_values, *cols[1:]])
    message = expect_error(path, "column 't_s'", *hints)
    assert "--resample" in message or "sort the rows" in message


def test_nan_cell(tmp_path):
    names, cols = good_columns()
    cols[2][7] = "nan"
    expect_error(write_csv(tmp_path, names, cols), "'y_cm'", "NaN at row 9")


def test_empty_cell_and_empty_column(tmp_path):
    names, cols = good_columns()
    cols[1][3] = ""
    expect_error(write_csv(tmp_path, names, cols), "'u_V'", "empty cell at row 5")
    cols[1] = [""] * N
    expect_error(write_csv(tmp_path, names, cols, "e.csv"), "'u_V'", "column is empty")


def test_non_numeric_cell(tmp_path):
    names, cols = good_columns()
    cols[2][10] = "12,5cm".replace(",", ".")
    expect_error(write_csv(tmp_path, names, cols), "'y_cm'", "'12.5cm' at row 12", "not a number")


def test_too_few_samples(tmp_path):
    names, cols = good_columns(5)
    expect_error(write_csv(tmp_path, names, cols), "only 5 samples", "at least 20")


def test_ragged_row_and_duplicate_signal(tmp_path):
    path = tmp_path / "ragged.csv"
    path.write_text("t_s,y_m\n0,1\n0.01,2,3\n", encoding="utf-8")
    expect_error(path, "row 3 has 3 cells")
    names, cols = good_columns()
    path = write_csv(tmp_path, [*names, "y_mm"], [*cols, [1] * N], "dup.csv")
    expect_error(path, "'y_mm'", "also given by column 'y_cm'")


def test_missing_file_and_bad_mapping(tmp_path):
    expect_error(tmp_path / "absent.csv", "file not found")
    names, cols = good_columns()
    path = write_csv(tmp_path, names, cols)
    expect_error(path, "columns names column 'yy'", mapping={"yy": "y_m"})


# -- mapping, .mat, resampling, split ------------------------------------------------------


def test_mapping_for_plain_headers(tmp_path):
    _, (t, u, y) = good_columns()
    path = write_csv(tmp_path, ["t", "r", "u", "y", "d"], [t, [0.1] * N, u, y, [2.0] * N])
    data = read_measured(
        path,
        mapping={"t": "t_s", "r": "ref_1", "u": "u_V", "y": "y_cm", "d": "d_mm"},
        require=("t", "u", "y"),
    )
    assert set(data.signals) == {"ref", "u", "y", "d"}
    np.testing.assert_allclose(data.signals["d"], 2e-3)
    np.testing.assert_allclose(data.signals["u"], u)
    np.testing.assert_allclose(data.signals["y"], np.asarray(y) * 1e-2)


def test_mat_round_trip(tmp_path):
    scipy_io = pytest.importorskip("scipy.io")
    t = np.arange(N) * T
    path = tmp_path / "run.mat"
    scipy_io.savemat(path, {"time": t, "p1_bar": np.full(N, 70.0), "pos": np.linspace(0, 10, N)})
    data = read_measured(path, mapping={"time": "t_s", "pos": "y_cm"}, require=("t", "y"))
    np.testing.assert_allclose(data.t, t)
    np.testing.assert_allclose(data.signals["p1"], 7e6)
    np.testing.assert_allclose(data.signals["y"], np.linspace(0, 0.1, N))
    # time from the sample period when the file has none
    scipy_io.savemat(path, {"u_V": np.ones((N, 1)), "y_m": np.zeros(N)})
    data = read_measured(path, sample_period_s=0.002)
    assert data.t[-1] == pytest.approx((N - 1) * 0.002)
    # bad variable: a matrix
    scipy_io.savemat(path, {"t_s": t, "y_m": np.zeros((N, 2))})
    expect_error(path, "variable 'y_m'", "matrix")


def test_resample_on_request(tmp_path):
    rng = np.random.default_rng(0)
    t = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0.0, 1.0, N - 2)]))
    t[5] = t[4]  # one repeated stamp
    path = write_csv(tmp_path, ["t_s", "u_V"], [list(t), list(2.0 * t + 1.0)])
    expect_error(path, "column 't_s'", "--resample")
    data = read_measured(path, resample=True)
    assert len(data) == N
    np.testing.assert_allclose(np.diff(data.t), 1.0 / (N - 1), rtol=1e-9)
    np.testing.assert_allclose(data.signals["u"], 2.0 * data.t + 1.0, rtol=1e-9)  # linear is exact


@pytest.mark.parametrize("fraction", [0.5, 0.7, 0.25])
def test_split_fractions(tmp_path, fraction):
    names, cols = good_columns(100)
    data = read_measured(write_csv(tmp_path, names, cols))
    train, held_out = data.split(fraction)
    assert len(train) == round(100 * fraction) and len(train) + len(held_out) == 100
    assert train.t[-1] < held_out.t[0]
    np.testing.assert_array_equal(np.concatenate([train.t, held_out.t]), data.t)
    with pytest.raises(ValueError):
        data.split(1.0)


def test_segment(tmp_path):
    names, cols = good_columns(100)
    data = read_measured(write_csv(tmp_path, names, cols))
    part = data.segment(0.2, 0.5)
    assert isinstance(part, Measured)
    assert part.t[0] == pytest.approx(0.2) and part.t[-1] == pytest.approx(0.49)
    assert part.sample_period_s == pytest.approx(T)
    with pytest.raises(ValueError):
        data.segment(0.5, 0.2)


# -- the real FASTER file (shared/data/faster, see SOURCE.txt there) -----------------------


@pytest.mark.skipif(not FASTER.is_file(), reason=f"FASTER data not present at {FASTER}")
def test_faster_file():
    # SOURCE.txt: t printed with 5 significant digits, so stamps repeat after t >= 100 s
    message = expect_error(
        FASTER, "column 't' (mapped to t_s)", "repeated time stamp", mapping=FASTER_MAPPING
    )
    assert "measured: sample_period" in message
    for kwargs in ({"sample_period_s": 0.0077531}, {"resample": True}):
        data = read_measured(FASTER, mapping=FASTER_MAPPING, require=("t", "u", "f"), **kwargs)
        assert len(data) == 21275
        assert data.sample_period_s == pytest.approx(0.0077531, rel=1e-4)  # ~128.98 Hz
        assert data.units == {"ref": "1", "u": "V", "f": "1", "d": "m"}
        assert np.all(np.abs(data.signals["d"]) < 0.1)  # mm -> m: beam moves millimetres
