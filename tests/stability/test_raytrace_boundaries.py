"""Ray tracing where links vanish: a UE inside a building, a link with no path, the scene edge.

One tiny scene: a 200 m x 200 m ground (medium dry ground) and one closed concrete block
40 m x 40 m x 20 m at the origin; Sionna RT through the package's own tracer
(:class:`LinkTracer`, reciprocal: rays launched from the UE) with max_depth 2, first-order
wedge diffraction, no refraction (the defaults except the depth). Boundaries found:

* **UE inside the closed building**: no valid path on any link (also with a depth of 3).
  The chain reports every BS undetected and a ``too_few_bs`` service failure; every output
  is finite. 0.5 m outside the wall the UE has 8 paths to each BS on that side.
* **link blocked completely**: a UE 5 m behind the block and a BS 60 m in front of it. Going
  over or around a 40 m deep block takes two edges, which first-order diffraction cannot do,
  so the link has no path while the BS is below the roof; once the BS is above the roof line
  (20 m) it sees the far roof edge: no path at 19.9 m, two at 20.1 m (the edge-diffracted
  path and its ground reflection). With that BS as the RSTD reference the chain reports
  "reference BS not detected" (service failure), not NaN.
* **scene edge**: the ground reflection exists while its specular point lies on the ground
  mesh: for a BS at x = 60 m, 25 m high and a UE 1.5 m high it disappears at
  x_UE = 60 + 40 * 26.5 / 25 = 102.4 m (found between 102.2 m and 102.6 m), 2.4 m beyond the
  scene's edge; the line of sight survives everywhere (also 900 m outside the scene, where
  only it and the block's backward edge diffraction remain).
"""

from pathlib import Path

import numpy as np
import pytest

from veriloc_rt.config.channel import ChannelConfig, ReceiverConfig
from veriloc_rt.config import ArrayConfig, RayTracingConfig
from veriloc_rt.constants import SPEED_OF_LIGHT
from veriloc_rt.config.nr import NRConfig
from veriloc_rt.propagation.cir import (INTERACTION_DIFFRACTION, INTERACTION_SPECULAR,
                                        ula_element_positions)
from veriloc_rt.propagation.raytrace import LinkTracer, build_cir, trace_links
from veriloc_rt.phy.chain import PositioningChain
from veriloc_rt.world.scene.canyon import UrbanCanyon
from veriloc_rt.world.scene.export import write_ply
from veriloc_rt.config.security import SecurityConfig
from veriloc_rt.phy.security.keys import simulated_keys

pytestmark = pytest.mark.raytrace

FC = 3.5e9
HALF = 100.0                                 # ground half-width, m
BLOCK = [-20.0, -20.0, 20.0, 20.0]
ROOF = 20.0
FID = RayTracingConfig(max_depth=2, diffraction=True, refraction=False, rays_per_source=20_000,
                       max_candidates_per_source=2000)
BS = np.array([[0.0, 60.0, 10.0], [-80.0, -45.0, 25.0], [80.0, -45.0, 25.0]])
#: float32 delays in Sionna RT: 1 ps is 0.3 mm of path
DELAY_TOL_S = 1e-12


def _write_scene(folder: Path) -> Path:
    """Ground + one closed box, materials as half-spaces (2 m thick, as tests/unit/propagation)."""
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    ground_v = np.array([[-HALF, -HALF, 0], [HALF, -HALF, 0], [HALF, HALF, 0], [-HALF, HALF, 0.0]])
    box_v, box_f = UrbanCanyon(np.array([BLOCK]), np.array([ROOF]), 5.0, 30.0, 1e4).box_meshes()
    meshes = {"ground": (ground_v, np.array([[0, 1, 2], [0, 2, 3]]), "medium_dry_ground"),
              "block": (box_v, box_f, "concrete")}
    lines = ['<scene version="2.1.0">']
    for name, (v, f, mat) in meshes.items():
        write_ply(folder / "meshes" / f"{name}.ply", v, f)
        lines += [f'<bsdf type="itu-radio-material" id="{name}_material">'
                  f'<string name="type" value="{mat}"/><float name="thickness" value="2.0"/></bsdf>',
                  f'<shape type="ply" id="mesh-{name}"><string name="filename" value="meshes/{name}.ply"/>'
                  f'<boolean name="face_normals" value="true"/><ref id="{name}_material" name="bsdf"/></shape>']
    lines.append("</scene>")
    (folder / "scene.xml").write_text("\n".join(lines))
    return folder / "scene.xml"


@pytest.fixture(scope="module")
def tracer(tmp_path_factory):
    return LinkTracer(_write_scene(tmp_path_factory.mktemp("stability_scene")), FC, FID, seed=1,
                      cache_dir=None)


@pytest.fixture(scope="module")
def chain():
    keys = simulated_keys((0, 1, 2), np.random.default_rng(0))
    return PositioningChain(NRConfig(slots_per_frame=4), SecurityConfig(), ChannelConfig(),
                            ReceiverConfig(), ArrayConfig(), FC, keys)


def _cir(tracer, ues, bs=BS):
    """CIR [num_ues, 3] of the links bs -> UE, traced from the UE side."""
    p = len(ues)
    raw = trace_links(tracer, np.repeat(bs[None], p, 0).reshape(-1, 3), np.repeat(ues, 3, 0),
                      reciprocal=True).project("V", "V")
    elem = ula_element_positions(5, 0.5 * SPEED_OF_LIGHT / FC, 0.0)
    return build_cir(raw, (p, 3), np.tile([0, 1, 2], (p, 1)), np.repeat(bs[None], p, 0), ues,
                     np.zeros((p, 3, 3)), np.zeros((p, 3)), FC, elem, FID.max_paths_per_link)


def _assert_finite(res):
    assert np.all(np.isfinite(res.position.position))
    assert np.all(np.isfinite(res.peak_snr_db)) and np.all(np.isfinite(res.doppler_hz))
    assert np.all(np.isfinite(res.toa_s[res.detected]))
    assert np.all(np.isnan(res.toa_s[~res.detected]))
    assert np.all(np.isfinite(res.uplink.position.position))


def test_ue_inside_a_closed_building_has_no_path(tracer, chain):
    ues = np.array([[0.0, 0.0, 1.5], [15.0, -12.0, 19.0],     # inside (ground floor, top floor)
                    [0.0, -20.5, 1.5]])                       # 0.5 m outside the south wall
    cir = _cir(tracer, ues)
    assert not cir.valid[:2].any()
    assert np.all(np.isnan(cir.first_path_delay()[:2]))
    assert cir.has_path()[2, 1:].all() and np.all(cir.valid[2, 1:].sum(-1) >= 3)
    for k in (0, 1):
        res = chain(cir, k, np.random.default_rng(k))
        _assert_finite(res)
        assert not res.detected.any() and not res.tags_valid.any()
        assert not res.position.ok and res.position.status == "too_few_bs"
        assert res.position.service_failure and not res.uplink.position.ok


def test_link_blocked_until_the_bs_clears_the_roof(tracer, chain):
    ue = np.array([[0.0, -25.0, 1.5]])                        # 5 m behind the block
    heights = (10.0, ROOF - 0.1, ROOF + 0.1, 40.0)
    found = []
    for h in heights:
        bs = BS.copy()
        bs[0, 2] = h
        cir = _cir(tracer, ue, bs)
        assert cir.has_path()[0, 1:].all()                    # the two BSs beside the block
        found.append(cir.valid[0, 0].sum())
        if h > ROOF:
            # over the far roof edge: every path of the link is diffracted there
            inter = cir.interactions[0, 0][cir.valid[0, 0]]
            assert np.all(np.any(inter == INTERACTION_DIFFRACTION, axis=-1))
        if h == 10.0:
            res = chain(cir, 0, np.random.default_rng(3))
            _assert_finite(res)
            assert list(res.detected) == [False, True, True]
            assert not res.position.ok and res.position.status == "too_few_bs"
            # the reference TRP is not heard: the fix falls back to the strongest heard one,
            # and two heard TRPs cannot make a 2-D fix
            assert res.position.reason == "2 BSs detected, 3 needed for a 2-D fix"
    assert found[0] == 0 and found[1] == 0                    # below the roof line: no path
    assert found[2] == 2 and found[3] == 2                    # above: edge, edge + ground


def test_ground_reflection_vanishes_where_its_specular_point_leaves_the_scene(tracer):
    bs = np.array([60.0, 5.0, 25.0])
    h_ue = 1.5
    x_edge = bs[0] + (HALF - bs[0]) * (bs[2] + h_ue) / bs[2]   # specular point at x = HALF
    assert x_edge == pytest.approx(102.4)
    xs = np.array([95.0, 101.0, x_edge - 0.2, x_edge + 0.2, 104.0, 110.0, 1000.0])
    ues = np.stack([xs, np.full(xs.size, 5.0), np.full(xs.size, h_ue)], axis=1)
    raw = tracer.trace(ues, np.repeat(bs[None], len(ues), 0))  # from the UEs
    for i, x in enumerate(xs):
        v = raw.valid[i]
        tau, inter = raw.tau[i][v], raw.interactions[i][v]
        n_int = np.count_nonzero(inter, axis=-1)
        los = np.abs(tau - np.linalg.norm(ues[i] - bs) / SPEED_OF_LIGHT) < DELAY_TOL_S
        img = np.abs(tau - np.linalg.norm(ues[i] - bs * [1, 1, -1]) / SPEED_OF_LIGHT) < DELAY_TOL_S
        ground = img & (n_int == 1) & (inter[:, 0] == INTERACTION_SPECULAR)
        assert np.any(los & (n_int == 0)), f"line of sight at x = {x}"
        assert ground.any() == (x < x_edge), f"ground reflection at x = {x}"
    # far outside the ground: the LoS, and nothing reflected on the UE's side (no ground under
    # it); the block behind the BS still diffracts backwards (one edge, found by the exhaustive
    # edge candidates), straight to the BS or via the ground between the block and the BS (a
    # plane 25 m below the BS: within FID.candidate_plane_distance_m of it)
    assert FID.candidate_plane_distance_m > bs[2]
    v = raw.valid[-1]
    inter = raw.interactions[-1][v]
    assert np.count_nonzero(np.all(inter == 0, axis=-1)) == 1
    kinds = {tuple(int(k) for k in row) for row in inter}
    assert kinds <= {(0, 0), (INTERACTION_DIFFRACTION, 0),
                     (INTERACTION_DIFFRACTION, INTERACTION_SPECULAR)}, kinds
    assert (INTERACTION_DIFFRACTION, 0) in kinds
