"""The ITU material table the config checks against is Sionna RT's own."""

import pytest

from veriloc_rt.config.world import ITU_MATERIAL_RANGES_GHZ, itu_material_problem


@pytest.mark.raytrace
def test_itu_material_table_matches_sionna():
    from veriloc_rt.backend import import_sionna

    import_sionna()  # selects the Mitsuba variant the module needs
    from sionna.rt.radio_materials.itu import ITU_MATERIALS_PROPERTIES

    assert {k: tuple(v) for k, v in ITU_MATERIALS_PROPERTIES.items()} == ITU_MATERIAL_RANGES_GHZ


def test_material_problems():
    assert itu_material_problem("concrete", 3.5e9) is None
    assert "unknown ITU material" in itu_material_problem("kryptonite", 3.5e9)
    # ITU-R P.2040-3 Table 3: floorboard is fitted from 50 GHz, ground types up to 10 GHz
    assert "50-100" in itu_material_problem("floorboard", 3.5e9)
    assert itu_material_problem("floorboard", 60e9) is None
    assert itu_material_problem("wet_ground", 28e9) is not None
