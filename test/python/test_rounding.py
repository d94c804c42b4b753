"""The Python scripts' rounding (scripts/accel_rounding.py) gives what the C++ text reports give
(src/io/rounding.cpp, test/io/rounding_test.cpp): the same cases worked by hand."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(
    os.path.realpath(__file__)))), "scripts"))

import pytest  # noqa: E402

from accel_rounding import with_uncertainty  # noqa: E402


@pytest.mark.parametrize("x,U,expected", [
    (414.90812, 0.016437, ("414.908", "0.016")),
    (1.0012345678, 0.000123, ("1.00123", "0.00012")),
    (-0.0314159, 0.00271, ("-0.0314", "0.0027")),
    (89.98765, 0.0115, ("89.988", "0.012")),
    (1234.5, 567.0, ("1230", "570")),
    (2.34567, 0.0996, ("2.35", "0.10")),
    (2.34567, 0.996, ("2.3", "1.0")),
    (2.34567, 0.994, ("2.35", "0.99")),
    (-0.00004, 0.0012, ("0.0000", "0.0012")),
    (9.80665432, float("nan"), ("9.806654", "n/a")),
    (1.5, 0.0, ("1.5", "n/a")),
])
def test_value_rounded_to_its_uncertainty(x, U, expected):
    assert with_uncertainty(x, U) == expected
