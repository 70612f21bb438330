"""Unit expressions: factors to SI and dimension checks."""

import math

import pytest

from fuzzyservo.units import parse_unit, to_si


@pytest.mark.parametrize(
    ("value", "unit", "si", "expected"),
    [
        (70, "bar", "Pa", 70e5),
        (18000, "bar", "Pa", 1.8e9),  # seed 002 §4: E = 18000 bar
        (3, "cm3", "m^3", 3e-6),
        (0.85, "g/cm3", "kg/m^3", 850.0),
        (10, "mA/V", "A/V", 0.01),
        (10, "ms", "s", 0.01),
        (1500, "rpm", "rad/s", 1500 * 2 * math.pi / 60),
        (0.1936, "V/cm", "V/m", 19.36),
        # seed 002 §4: a = 0.2221 l/(min·sqrt(bar)) = 0.2221e-3/60 m³/s per sqrt(1e5 Pa)
        (0.2221, "l/(min*sqrt(bar))", "m^3/(s*sqrt(Pa))", 0.2221e-3 / 60 / math.sqrt(1e5)),
        (0.06, "l/(min*mA*sqrt(bar))", "m^3/(s*A*sqrt(Pa))", 0.06e-3 / 60 / 1e-3 / math.sqrt(1e5)),
        (47.2298, "cm3/(s*sqrt(bar))", "m^3/(s*sqrt(Pa))", 47.2298e-6 / math.sqrt(1e5)),
        (2.95e-3, "N*m*s/rad", "N*m*s/rad", 2.95e-3),
        (1, "m^5/(N*s)", "m^5/(N*s)", 1.0),
    ],
)
def test_conversions(value, unit, si, expected):
    assert to_si(value, unit, si) == pytest.approx(expected, rel=1e-12)


def test_dimension_mismatch_names_both_units():
    with pytest.raises(ValueError, match=r"'bar'.*does not fit.*'m'"):
        to_si(1.0, "bar", "m")


def test_unknown_unit_is_named():
    with pytest.raises(ValueError, match="unknown unit 'furlong'"):
        parse_unit("furlong/s")


def test_garbage_unit():
    with pytest.raises(ValueError, match="cannot read unit"):
        parse_unit("m/(s")


def test_the_units_the_tables_print_parse():
    """The metric tables write ``mm²·s`` and ``(rad/s)²·s``: both read back as units."""
    assert to_si(1.0, "mm²·s", "m^2*s") == pytest.approx(1e-6)
    assert parse_unit("(rad/s)²·s") == parse_unit("rad^2/s")
