"""Argument checks shared by every public entry point.

Each check returns the value in its canonical Python/numpy form or raises with a
message that names the argument, the allowed range (with its unit) and the value
given. Python and numpy numbers are accepted alike (``np.float32(0.01)``,
``np.int64(3)``); booleans, complex numbers, strings and objects are not numbers here.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np


class UserError(ValueError):
    """A value or a request the project refuses: the user's mistake, not a bug.

    Raised by the checks here and by the agents' own (a spec, a run folder, a flag); the
    command lines turn it into one line and exit status 2, where any other exception is a
    bug and shows its traceback. A ValueError, so ``except ValueError`` still catches it.
    """


class UserTypeError(UserError, TypeError):
    """A `UserError` about a value's type (a string where a number goes): a TypeError as well."""


class UserKeyError(UserError, KeyError):
    """A `UserError` that names something not there (a parameter, a hyperparameter block, a
    shipped solution): a KeyError (and a LookupError) as well, shown without KeyError's quotes.
    """

    def __str__(self) -> str:
        return str(self.args[0]) if len(self.args) == 1 else super().__str__()


# integration tolerances that keep the physics honest: looser ones let steps jump over
# the 2 cm critical band and overflow the event log; tighter ones ask for more digits
# than float64 has (rtol 1e-14 already needs ~120,000 right-hand sides for task b)
RTOL_RANGE = (1e-14, 1e-2)
ATOL_RANGE = (1e-16, 1e-2)


def _interval(low: float, high: float, low_open: bool, high_open: bool) -> str:
    if math.isinf(low) and math.isinf(high):
        return "any finite value"
    if math.isinf(high):
        return f"{'>' if low_open else '>='} {low:g}"
    if math.isinf(low):
        return f"{'<' if high_open else '<='} {high:g}"
    return f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"


def _unit(unit: str) -> str:
    return f" [{unit}]" if unit else ""


def is_real(value: Any) -> bool:
    """A Python or numpy real number (0-d real arrays too), not a bool."""
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in "iuf"
    return isinstance(value, (numbers.Real, np.integer, np.floating))


def real(name: str, value: Any, low: float = -math.inf, high: float = math.inf, *, unit: str = "",
         low_open: bool = False, high_open: bool = False) -> float:
    """A finite real number in the interval, as a float."""
    if type(value) is float:  # the common case, checked without building the message
        number = value
    elif is_real(value):
        number = float(value)
    else:
        raise UserTypeError(f"{_real_text(name, low, high, unit, low_open, high_open)}, got {value!r} "
                            f"({type(value).__name__})")
    inside = math.isfinite(number) and (low < number if low_open else low <= number) and (
        number < high if high_open else number <= high)
    if not inside:
        raise UserError(f"{_real_text(name, low, high, unit, low_open, high_open)}, got {value!r}")
    return number


def _real_text(name: str, low: float, high: float, unit: str, low_open: bool, high_open: bool) -> str:
    return f"{name} must be a finite number {_interval(low, high, low_open, high_open)}{_unit(unit)}"


def integer(name: str, value: Any, low: int, high: int | None = None) -> int:
    """A Python or numpy integer (not a bool, not a float) in [low, high], as an int."""
    text = f"{name} must be an integer >= {low}" if high is None else \
        f"{name} must be an integer in [{low}, {high}]"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
        raise UserTypeError(f"{text}, got {value!r} ({type(value).__name__})")
    if value < low or (high is not None and value > high):
        raise UserError(f"{text}, got {value!r}")
    return int(value)


def flag(name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise UserTypeError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def choice(name: str, value: Any, allowed) -> Any:
    """One of the allowed values, of the same type (so 1 is not True and not "1")."""
    allowed = tuple(allowed)
    if not any(type(value) is type(a) and value == a for a in allowed):
        raise UserError(f"{name} must be one of {', '.join(repr(a) for a in allowed)}, got {value!r}")
    return value


def real_array(name: str, value: Any, shape: tuple[int, ...], *, unit: str = "", low=None, high=None,
               range_text: str = "") -> np.ndarray:
    """A float64 C-contiguous array of the given shape, finite and (where bounds are given)
    inside [low, high] elementwise. Lists, tuples and arrays of real numbers are accepted;
    complex, boolean, string and object contents are not.
    """
    what = f"{name} must be {_count(shape)} finite numbers{_unit(unit)}"
    if not range_text and (low is not None or high is not None):  # the message names the allowed range
        range_text = (f"every entry in [{low:g}, {high:g}]" if low is not None and high is not None
                      else f"every entry >= {low:g}" if low is not None else f"every entry <= {high:g}")
    if range_text:
        what += f" with {range_text}"
    try:
        array = np.asarray(value)
    except (TypeError, ValueError):
        raise UserTypeError(f"{what}, got {value!r}") from None
    if array.dtype.kind not in "iuf":
        kind = {"c": "complex", "b": "boolean", "U": "text", "S": "bytes", "O": "non-numeric"}.get(
            array.dtype.kind, array.dtype.name)
        raise UserTypeError(f"{what}, got {kind} values {value!r}")
    if array.shape != shape:
        raise UserError(f"{what} (shape {shape}), got shape {array.shape}")
    array = np.ascontiguousarray(array, dtype=np.float64)
    if not np.isfinite(array).all():
        raise UserError(f"{what}, got {_show(array)}")
    if (low is not None and np.any(array < low)) or (high is not None and np.any(array > high)):
        raise UserError(f"{what}, got {_show(array)}")
    return array


def _show(array: np.ndarray):
    """The values, shortened for large batches (a message must stay readable)."""
    return array.tolist() if array.size <= 12 else np.array2string(array, threshold=12, separator=", ")


def _count(shape: tuple[int, ...]) -> str:
    return str(shape[0]) if len(shape) == 1 else "x".join(str(n) for n in shape)


def tolerance(name: str, value: Any) -> float:
    """rtol or atol inside RTOL_RANGE / ATOL_RANGE."""
    low, high = {"rtol": RTOL_RANGE, "atol": ATOL_RANGE}[name]
    return real(name, value, low, high)


TOLERANCE_WEIGHT_RANGE = (1e-3, 1e3)


def tolerance_weights(value: Any, groups: dict) -> np.ndarray:
    """A factor on rtol and atol per state component from None (all 1) or a dict of group name
    (a key of groups, which maps it to its slice of the state) to a factor in TOLERANCE_WEIGHT_RANGE.
    """
    weights = np.ones(max(part.stop for part in groups.values()))
    for group, factor in mapping("tolerance_weights", value, groups).items():
        weights[groups[group]] = real(f"tolerance_weights[{group!r}]", factor, *TOLERANCE_WEIGHT_RANGE)
    return weights


def mapping(name: str, value: Any, allowed_keys) -> dict:
    """None (an empty dict) or a mapping whose keys are among allowed_keys."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise UserTypeError(f"{name} must be a dict (or None) with keys among {sorted(allowed_keys)}, "
                            f"got {value!r}")
    unknown = [key for key in value if key not in allowed_keys]
    if unknown:
        raise UserError(f"unknown {name} {sorted(map(str, unknown))}; allowed: {sorted(allowed_keys)}")
    return dict(value)


def seed(name: str, value: Any) -> int | None:
    """None or an integer >= 0 (numpy integers too), as Gymnasium's seeding needs."""
    return None if value is None else integer(name, value, 0)
