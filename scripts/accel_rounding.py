"""Numbers for people, in the Python scripts (certificate_report, supervise): a value rounded to
its uncertainty, the uncertainty to two significant digits and the value to the same decimal
place (GUM 7.2.6; docs/design.md section 15). The same rule as src/io/rounding.cpp, which the
C++ text reports use; JSON keeps every digit."""
import math


def decimals_for(U):
    """Decimal places that keep two significant digits of U (negative: tens, hundreds...)."""
    return 1 - int(math.floor(math.log10(abs(U))))


def round_half_away(x, d):
    """x rounded to d decimal places (d < 0: tens, hundreds...), halves away from zero, scaled
    as src/io/rounding.cpp does (std::round(x * 10^d) / 10^d), so both print the same digits."""
    scale = 10.0 ** d
    scaled = x * scale
    a = abs(scaled)
    r = math.floor(a)
    if a - r >= 0.5:
        r += 1
    return math.copysign(r, scaled) / scale


def fmt_fixed(x, d):
    x = round_half_away(x, d)
    if x == 0:
        x = 0.0  # no "-0.000"
    if d > 0:
        return "%.*f" % (d, x)
    return "%d" % int(x)


def with_uncertainty(x, U):
    """(value, U) as strings rounded per GUM 7.2.6: 414.90812, 0.016437 -> ("414.908", "0.016")."""
    if x is None or not isinstance(x, (int, float)) or not math.isfinite(x):
        return "n/a", "n/a"
    if U is None or not isinstance(U, (int, float)) or not math.isfinite(U) or U <= 0:
        return "%.7g" % x, "n/a"
    d = decimals_for(U)
    Ur = round_half_away(U, d)
    if Ur > 0 and decimals_for(Ur) != d:  # 0.0995 -> 0.10: still two digits at the new place
        d = decimals_for(Ur)
    return fmt_fixed(x, d), fmt_fixed(U, d)
