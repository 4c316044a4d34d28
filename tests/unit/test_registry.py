"""The plug-in registry class and the built-in entries of each family."""

from __future__ import annotations

import pytest

from veriloc_rt.attacks.threats import THREAT_REGISTRY, Threat, scenario_names
from veriloc_rt.detectors.outcomes import DETECTORS
from veriloc_rt.detectors.registry import DETECTOR_REGISTRY
from veriloc_rt.errors import InputError
from veriloc_rt.propagation.models import PROPAGATION_REGISTRY
from veriloc_rt.registry import Registry


def test_register_lookup_and_errors():
    reg = Registry("widget", "section.widget")

    @reg.register("a")
    class A:
        pass

    def b():
        return 1

    reg.register("b", b)   # any object; a class also gets its name
    assert reg.names() == ("a", "b") and A.name == "a" and reg.get("b") is b
    assert "a" in reg and len(reg) == 2
    with pytest.raises(ValueError, match="already registered"):
        reg.register("a", A)
    for bad in ("", "a b", "x.y", 3):
        with pytest.raises(ValueError):
            reg.register(bad, A)
    with pytest.raises(InputError) as e:
        reg.get("c")
    assert str(e.value) == "section.widget: unknown widget 'c'; registered: 'a', 'b'"
    with pytest.raises(InputError, match=r"^other\[2\]: "):
        reg.get("c", "other[2]")
    reg.unregister("a")
    assert reg.names() == ("b",)


def test_built_ins_are_registered_in_order():
    assert scenario_names()[:4] == ("none", "fbs", "meaconing", "jamming")
    assert all(issubclass(THREAT_REGISTRY.get(n), Threat) for n in ("fbs", "meaconing", "jamming"))
    # the random streams of the built-in threats keep their indices (same draws as before)
    assert [THREAT_REGISTRY.get(n).stream_index for n in ("fbs", "meaconing", "jamming")] == [1, 2, 3]
    assert [n for n in ("fbs", "meaconing", "jamming")
            if THREAT_REGISTRY.get(n).relays] == ["meaconing"]
    assert DETECTOR_REGISTRY.names()[:5] == DETECTORS
    assert PROPAGATION_REGISTRY.names()[:3] == ("raytrace", "uma", "umi")
