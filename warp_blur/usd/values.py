"""Attribute values read as NumPy arrays, with the one failure USD leaves to its callers: a value
authored with a type name USD does not know (`in[] faceVertexIndices`, a typo or a damaged file)
composes, and reads back as an `Sdf.UnregisteredValue` that no array conversion accepts."""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd


class UnreadableValue(ValueError):
    """An attribute's value is no array of numbers (its message names the attribute); the scene
    treats the prim as invalid geometry (an error, or dropped with --skip-invalid)."""


def unregistered(value) -> bool:
    """True for a value authored with a type USD does not know."""
    return isinstance(value, Sdf.UnregisteredValue)


def _unknown_type(attr: Usd.Attribute, time: Usd.TimeCode) -> UnreadableValue:
    """The error for attr's value of an unknown type, naming the attribute and the type authored."""
    stack = attr.GetPropertyStack(time)
    authored = stack[0].GetInfo("typeName") if stack else "?"
    return UnreadableValue(f"{attr.GetPath()} is authored with type '{authored}', which USD does not know")


def array_value(attr: Usd.Attribute, time: Usd.TimeCode, dtype) -> np.ndarray:
    """attr's value at `time` as a NumPy array of dtype (empty when it has none); UnreadableValue
    when it cannot be one."""
    value = attr.Get(time)
    if value is None:
        return np.zeros(0, dtype)
    if unregistered(value):
        raise _unknown_type(attr, time)
    try:
        return np.asarray(value, dtype)
    except (TypeError, ValueError):
        raise UnreadableValue(f"{attr.GetPath()} is not an array of numbers") from None


def value_count(attr: Usd.Attribute, time: Usd.TimeCode) -> int:
    """How many elements attr's array value holds at `time` (0 when it has none); UnreadableValue
    when the value is of a type USD does not know."""
    value = attr.Get(time)
    if value is None:
        return 0
    if unregistered(value):
        raise _unknown_type(attr, time)
    return len(value)
