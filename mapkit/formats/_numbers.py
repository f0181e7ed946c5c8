"""Text to numbers as ARIA's C library reads them (``strtol``, ``atoi``, ``strtod``), linearly.

Every place the ``.map`` and ``.2d`` readers turn text into a number goes through this module, so
that a file reads the same everywhere and no input can raise a foreign exception or take more
than linear time:

* :func:`strtol` is C's ``strtol`` (64-bit ``long``): optional sign, decimal or hexadecimal
  digits (with an optional ``0x`` in base 16), saturation at ``LONG_MIN``/``LONG_MAX``.
* :func:`strtod` is glibc's ``strtod``: decimal and hexadecimal (``0x1.8p3``) numbers,
  ``inf``/``infinity``/``nan``/``nan(...)`` in any case, correctly rounded, ``inf`` on overflow
  and ``0`` or a subnormal on underflow.
* :func:`aria_int` and :func:`aria_double` are ARIA's ``ArArgumentBuilder::getArgInt`` and
  ``getArgDouble`` on one whole token: ``getArgInt`` strips a ``0x`` prefix from a token longer
  than 2 characters and reads the rest in base 16 (so ``0x-10`` is -16 and ``+0x10`` is refused),
  and keeps the ``long`` in a 32-bit ``int`` (:func:`c_int`: 99999999999999999999 reads as -1).
* :func:`atoi` is what ARIA's data-row reader applies to a run of digits (``strtol`` in base 10);
  mapkit keeps the 64-bit value rather than ARIA's 32-bit cast (the validator reports rows
  beyond 32 bits).

Python's own ``int()`` and ``float()`` are not used on file text: ``int()`` refuses more than
4,300 digits, ``float()`` accepts ``1_000`` and refuses ``0x10``, and neither saturates.

Examples:
    >>> strtol("-0x1fz", 16), strtol("12abc"), strtol("abc")
    ((-31, 5), (12, 2), (0, 0))
    >>> strtol("9" * 50_000)[0] == 2**63 - 1
    True
    >>> strtod("1e400"), strtod("0x1.8p1"), strtod("INFINITY"), strtod("1.5e"), strtod("e5")
    ((inf, 5), (3.0, 7), (inf, 8), (1.5, 3), (0.0, 0))
    >>> aria_int("0x10"), aria_int("0x-10"), aria_int("+0x10"), aria_int("12abc")
    (16, -16, None, None)
    >>> c_int(aria_int("99999999999999999999")), c_int(4294967297)
    (-1, 1)
    >>> aria_double("-INF"), aria_double("0x10"), aria_double("1.5x")
    (-inf, 16.0, None)
"""

from __future__ import annotations

import math
import re

__all__ = [
    "LONG_MAX",
    "LONG_MIN",
    "aria_double",
    "aria_int",
    "atoi",
    "c_int",
    "strtod",
    "strtol",
    "token_double",
    "token_long",
]

LONG_MAX = 2**63 - 1
LONG_MIN = -(2**63)
_INT_BITS = 32

_SPACE = re.compile(r"[ \t\n\x0b\x0c\r]*")
_DEC_DIGITS = re.compile(r"[0-9]*")
_HEX_DIGITS = re.compile(r"[0-9a-fA-F]*")
_HEX_PREFIX = re.compile(r"0[xX](?=[0-9a-fA-F])")
_HEX_FLOAT_PREFIX = re.compile(r"0[xX](?=[0-9a-fA-F]|\.[0-9a-fA-F])")
_DEC_EXPONENT = re.compile(r"[eE]([+-]?)([0-9]+)")
_HEX_EXPONENT = re.compile(r"[pP]([+-]?)([0-9]+)")
_NAN_PAYLOAD = re.compile(r"\([0-9A-Za-z_]*\)")
# A plain decimal that Python's float() reads exactly as strtod does (no '_', no words).
_PLAIN = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")

# Correct rounding needs at most 767 significant decimal digits (17 hex digits cover the 53 bits
# of a double); the digits past these are replaced by one non-zero "sticky" digit, which rounds
# the same way. Exponents beyond these bounds are infinity or zero whatever the digits are.
_MAX_DEC_DIGITS = 800
_MAX_HEX_DIGITS = 20
_MAX_EXP_DIGITS = 12


def _skip_space(s: str, pos: int) -> int:
    m = _SPACE.match(s, pos)
    return m.end() if m else pos


def _sign(s: str, pos: int) -> tuple[bool, int]:
    if pos < len(s) and s[pos] in "+-":
        return s[pos] == "-", pos + 1
    return False, pos


def strtol(s: str, base: int = 10) -> tuple[int, int]:
    """C's ``strtol`` on ``s`` (base 10 or 16): ``(value, characters used)``.

    No digits: ``(0, 0)`` (C sets ``endptr`` to the start). The value saturates at the 64-bit
    ``long`` limits.
    """
    if base not in (10, 16):
        raise ValueError(f"base must be 10 or 16, not {base}")
    pos = _skip_space(s, 0)
    neg, pos = _sign(s, pos)
    if base == 16:
        m = _HEX_PREFIX.match(s, pos)
        if m:
            pos = m.end()
        digits_re = _HEX_DIGITS
    else:
        digits_re = _DEC_DIGITS
    m = digits_re.match(s, pos)
    digits = m.group() if m else ""
    if not digits:
        return 0, 0
    sig = digits.lstrip("0")
    # 2**63 has 19 decimal or 16 hexadecimal digits: more significant digits always saturate.
    if len(sig) > (19 if base == 10 else 16):
        value = LONG_MIN if neg else LONG_MAX
    else:
        value = int(sig or "0", base)
        value = -value if neg else value
        value = min(max(value, LONG_MIN), LONG_MAX)
    return value, pos + len(digits)


def _exponent(sign: str, digits: str) -> int:
    """An exponent's digits as an int, clamped far beyond any double's range."""
    sig = digits.lstrip("0")
    value = 10**_MAX_EXP_DIGITS if len(sig) > _MAX_EXP_DIGITS else int(sig or "0")
    return -value if sign == "-" else value


def _significand(whole: str, frac: str, exp: int, step: int, keep: int) -> tuple[str, int] | None:
    """``whole.frac * base**exp`` as significant digits and an exponent in units of ``step``.

    ``step`` is 1 for decimal digits (powers of 10) and 4 for hexadecimal ones (powers of 2).
    Leading and trailing zeros go; digits past ``keep`` become one sticky ``1``. ``None`` for 0.
    """
    mant = (whole + frac).lstrip("0")
    exp -= step * len(frac)
    stripped = mant.rstrip("0")
    exp += step * (len(mant) - len(stripped))
    mant = stripped
    if not mant:
        return None
    if len(mant) > keep:
        exp += step * (len(mant) - keep - 1)
        mant = mant[:keep] + "1"
    return mant, exp


def _value(neg: bool, whole: str, frac: str, exp: int, hexa: bool) -> float:
    step, keep, top, bottom = (
        (4, _MAX_HEX_DIGITS, 1100, -1200) if hexa else (1, _MAX_DEC_DIGITS, 310, -330)
    )
    found = _significand(whole, frac, exp, step, keep)
    if found is None:
        return -0.0 if neg else 0.0
    mant, exp = found
    magnitude = step * len(mant) + exp  # value < base**magnitude, >= base**(magnitude - step)
    if magnitude > top:
        value = math.inf
    elif magnitude < bottom:
        value = 0.0
    elif hexa:
        try:
            value = float.fromhex(f"0x{mant}p{exp}")
        except OverflowError:  # rounds up past the largest double
            value = math.inf
    else:
        value = float(f"{mant}e{exp}")
    return -value if neg else value


def strtod(s: str) -> tuple[float, int]:
    """glibc's ``strtod`` on ``s`` (C locale): ``(value, characters used)``; ``(0.0, 0)``: none."""
    if len(s) < 40 and _PLAIN.fullmatch(s):
        return float(s), len(s)  # the common case: what ARIA and mapkit write
    pos = _skip_space(s, 0)
    neg, pos = _sign(s, pos)
    low = s[pos : pos + 8].lower()
    if low.startswith("inf"):
        used = 8 if low == "infinity" else 3
        return (-math.inf if neg else math.inf), pos + used
    if low.startswith("nan"):
        pos += 3
        m = _NAN_PAYLOAD.match(s, pos)
        if m:
            pos = m.end()
        return (-math.nan if neg else math.nan), pos
    hexa = _HEX_FLOAT_PREFIX.match(s, pos)
    if hexa:
        pos = hexa.end()
    digits_re, exp_re = (_HEX_DIGITS, _HEX_EXPONENT) if hexa else (_DEC_DIGITS, _DEC_EXPONENT)
    m = digits_re.match(s, pos)
    whole = m.group() if m else ""
    pos += len(whole)
    frac = ""
    if pos < len(s) and s[pos] == ".":
        m = digits_re.match(s, pos + 1)
        frac = m.group() if m else ""
        if whole or frac:
            pos += 1 + len(frac)
    if not whole and not frac:
        return 0.0, 0
    exp = 0
    m = exp_re.match(s, pos)
    if m:
        exp = _exponent(m.group(1), m.group(2))
        pos = m.end()
    return _value(neg, whole, frac, exp, bool(hexa)), pos


def token_long(tok: str, base: int = 10) -> int | None:
    """``strtol`` on a whole token: the value, or ``None`` unless every character was used."""
    value, used = strtol(tok, base)
    return value if used and used == len(tok) else None


def token_double(tok: str) -> float | None:
    """``strtod`` on a whole token: the value, or ``None`` unless every character was used."""
    if tok.isascii() and tok.isprintable() and "_" not in tok and " " not in tok:
        # On printable ASCII without blanks or "_" (nothing to strip, no Unicode digits, no digit
        # separators) Python's float() takes exactly the decimal, inf and nan spellings strtod
        # takes whole, rounds them the same, in linear time, and faster; hexadecimal floats and
        # nan(...) fall through to strtod.
        try:
            return float(tok)
        except ValueError:
            pass
    value, used = strtod(tok)
    return value if used and used == len(tok) else None


def aria_int(tok: str) -> int | None:
    """ARIA's ``getArgInt`` on one token before its cast to ``int``: the ``long``, or ``None``.

    A token longer than 2 characters starting ``0x``/``0X`` is read in base 16 after the prefix
    (``strtol`` then also takes a sign and a second ``0x``); any other token in base 10. Apply
    :func:`c_int` for the 32-bit value ARIA keeps.
    """
    if len(tok) > 2 and tok[0] == "0" and tok[1] in "xX":
        return token_long(tok[2:], 16)
    return token_long(tok, 10)


def c_int(value: int) -> int:
    """A ``long`` cast to a 32-bit C ``int`` (two's complement wrap, as GCC does)."""
    half = 1 << (_INT_BITS - 1)
    return ((value + half) % (1 << _INT_BITS)) - half


def aria_double(tok: str) -> float | None:
    """ARIA's ``getArgDouble`` on one token (``INF``/``-INF`` or a whole ``strtod``) or ``None``."""
    return token_double(tok)


def atoi(digits: str) -> int:
    """The value of a data-row number (``-`` then decimal digits, or digits; ``-`` alone is 0).

    ``strtol`` in base 10, saturating at the 64-bit limits; ARIA's ``atoi`` would further cut
    it to 32 bits (:func:`c_int`).
    """
    return strtol(digits, 10)[0]
