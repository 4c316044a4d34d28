"""Hypothesis strategies drawing values that the config's JSON schema accepts."""

from __future__ import annotations

from hypothesis import strategies as st


def from_schema(s: dict, text_size: int = 12, list_size: int = 5) -> st.SearchStrategy:
    """Values valid for one node of the config's JSON schema (all properties optional).

    :param text_size: longest string drawn;  list_size: longest array drawn
    """
    def node(x: dict) -> st.SearchStrategy:
        return from_schema(x, text_size, list_size)

    if "enum" in s:
        return st.sampled_from(s["enum"])
    if "anyOf" in s:  # an optional field: its range sits beside the alternatives
        bounds = {k: v for k, v in s.items() if k in ("minimum", "exclusiveMinimum", "maximum")}
        return st.one_of([node({**x, **bounds} if x["type"] in ("number", "integer") else x)
                          for x in s["anyOf"]])
    t = s["type"]
    if t == "object":
        return st.fixed_dictionaries({}, optional={k: node(v) for k, v in s["properties"].items()})
    if t == "integer":
        return st.integers(s.get("minimum"), s.get("maximum"))
    if t == "number":
        lo = s.get("minimum", s.get("exclusiveMinimum"))
        return st.floats(lo, s.get("maximum"), exclude_min="exclusiveMinimum" in s,
                         allow_nan=False, allow_infinity=False)
    if t == "boolean":
        return st.booleans()
    if t == "string":
        return st.text(max_size=text_size)
    if t == "null":
        return st.none()
    if t == "array":
        return st.lists(node(s["items"]), max_size=list_size)
    raise AssertionError(f"schema node {s}")
