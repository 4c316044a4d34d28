"""BS antennas (veriloc_rt.propagation.antenna): the TR 38.901 Table 7.3-1 element, the tilted
column's array factor, the sector transform of a CIR and the isotropic default.

Each expectation is derived here from the formulas, not from the module:
* Table 7.3-1: A_V = -min(12 ((theta - 90) / 65)^2, 30), A_H = -min(12 (phi / 65)^2, 30),
  A = 8 - min(-(A_V + A_H), 30) dBi;
* the column: |sum_m exp(j m psi)| / sqrt(M) = |sin(M psi / 2) / sin(psi / 2)| / sqrt(M) with
  psi = 2 pi d_V (cos theta - cos theta_tilt) (a geometric series), peak sqrt(M) at psi = 0,
  first null at psi = 2 pi / M.
Tolerances: 1e-12 relative (the same closed forms evaluated in float64; only rounding differs).
"""

import dataclasses
import math

import numpy as np
import pytest

from veriloc_rt.config import TopologyConfig
from veriloc_rt.propagation.antenna import (ElementPattern, SectorPanel, apply_bs_antenna,
                                            apply_sectors, column_array_factor,
                                            describe_bs_antenna, element_pattern_db,
                                            sector_boresights)
from veriloc_rt.propagation.cir import CIR, NO_TX
from veriloc_rt.propagation.raytrace import Propagation

RTOL = 1e-12   # float64 rounding of the same closed forms


# -- element (Table 7.3-1) ------------------------------------------------------------------
@pytest.mark.parametrize("theta, phi, expect", [
    (90.0, 0.0, 8.0),                        # boresight: G_E,max
    (90.0, 32.5, 8.0 - 3.0),                 # half the 65 deg beamwidth: 12 (1/2)^2 = 3 dB
    (90.0, -32.5, 8.0 - 3.0),
    (122.5, 0.0, 8.0 - 3.0),                 # the same in the vertical cut
    (90.0, 180.0, 8.0 - 30.0),               # behind: A_H floor A_max = 30 dB
    (0.0, 0.0, 8.0 - 12.0 * (90.0 / 65.0) ** 2),   # zenith: A_V = -23.0 dB (no floor)
    (180.0, 100.0, 8.0 - 30.0),              # A_V + A_H = -51.4 dB, capped at A_max
    (100.0, 20.0, 8.0 - 12.0 * (10 / 65) ** 2 - 12.0 * (20 / 65) ** 2),
    (90.0, 360.0 + 32.5, 8.0 - 3.0),         # azimuth wraps
])
def test_element_pattern_matches_table_7_3_1(theta, phi, expect):
    assert element_pattern_db(theta, phi) == pytest.approx(expect, rel=RTOL, abs=1e-12)


def test_element_vertical_side_lobe_floor():
    # with 65 deg beams A_V never reaches SLA_V in [0, 180] deg (12 (90/65)^2 = 23 dB < 30);
    # a 30 deg element reaches it: 12 (90/30)^2 = 108 dB -> floor SLA_V = 20 dB (A_max 40)
    el = ElementPattern(theta_3db_deg=30.0, sla_v_db=20.0, a_max_db=40.0)
    assert element_pattern_db(0.0, 0.0, el) == pytest.approx(8.0 - 20.0, rel=RTOL)
    assert element_pattern_db(180.0, 0.0, el) == pytest.approx(8.0 - 20.0, rel=RTOL)


# -- column array factor ----------------------------------------------------------------------
def _dirichlet(theta, m, d, tilt):
    psi = 2 * np.pi * d * (np.cos(theta) - np.cos(tilt))
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.abs(np.sin(m * psi / 2) / np.sin(psi / 2))
    return np.where(np.abs(np.sin(psi / 2)) < 1e-15, m, r) / math.sqrt(m)


@pytest.mark.parametrize("m, d, tilt_deg", [(10, 0.5, 102.0), (10, 0.8, 102.0), (8, 0.5, 96.0)])
def test_column_array_factor_closed_form(m, d, tilt_deg):
    tilt = math.radians(tilt_deg)
    theta = np.radians(np.linspace(1.0, 179.0, 357))
    got = column_array_factor(theta, m, d, tilt)
    np.testing.assert_allclose(np.abs(got), _dirichlet(theta, m, d, tilt), rtol=1e-9, atol=1e-12)
    # the phase reference is the column's centre: the factor is real
    np.testing.assert_allclose(got.imag, 0.0, atol=1e-12)
    # peak at the tilt direction: sqrt(M), i.e. 10 lg M dB
    assert abs(column_array_factor(np.array(tilt), m, d, tilt)) == pytest.approx(math.sqrt(m),
                                                                                rel=RTOL)


def test_column_null_and_explicit_phasor_sum():
    m, d, tilt = 10, 0.5, math.radians(102.0)
    # first null: psi = 2 pi / M -> cos theta = cos tilt + 1 / (M d)
    null = math.acos(math.cos(tilt) + 1.0 / (m * d))
    assert abs(column_array_factor(np.array(null), m, d, tilt)) < 1e-12
    # explicit sum of the M phasors (elements at 0 .. M-1 from the bottom: same magnitude)
    for th in np.radians([60.0, 85.0, 95.4, 102.0, 130.0]):
        s = sum(np.exp(1j * 2 * np.pi * k * d * (np.cos(th) - np.cos(tilt))) for k in range(m))
        assert abs(column_array_factor(np.array(th), m, d, tilt)) == pytest.approx(
            abs(s) / math.sqrt(m), rel=1e-12)


def test_panel_peak_gain():
    # at the tilt direction on boresight: element 8 - 12 (12/65)^2 dB, column 10 lg 10 dB
    p = SectorPanel(num_elements=10, spacing_wavelengths=0.5, tilt_deg=102.0)
    assert p.peak_gain_dbi() == pytest.approx(8.0 - 12.0 * (12 / 65) ** 2 + 10.0, rel=RTOL)
    assert "17.6 dBi" in describe_bs_antenna(TopologyConfig(bs_antenna="tr38901"))
    assert describe_bs_antenna(TopologyConfig()) == "isotropic 0 dBi"


# -- the CIR transform ------------------------------------------------------------------------
def _cir(aod_az, aod_zen, amp, tx_index):
    """One point, len(tx_index) link slots, len(aod_az[0]) paths each, two UE antennas."""
    aod_az, aod_zen, amp = (np.asarray(x, float)[None] for x in (aod_az, aod_zen, amp))
    p, t, n = aod_az.shape
    gains = np.repeat(amp[:, :, None, :], 2, axis=2) * np.exp(1j * 0.3)
    z = np.zeros((p, t, n))
    return CIR(delays=np.full((p, t, n), 1e-6), gains=gains.astype(complex), aoa_az=z,
               aoa_zen=z, aod_az=aod_az, aod_zen=aod_zen, doppler=z,
               interactions=np.zeros((p, t, n, 1), np.uint8), valid=np.ones((p, t, n), bool),
               tx_index=np.asarray(tx_index, np.int64)[None], tx_pos=np.zeros((p, t, 3)),
               rx_pos=np.zeros((p, 3)), los=np.ones((p, t), bool), carrier_frequency=3.5e9)


def _expected_field(zen, rel_az_deg, m=10, d=0.5, tilt_deg=102.0):
    """sqrt(A) from Table 7.3-1 times the column's phasor sum, written out here."""
    th = math.degrees(zen)
    a_v = -min(12 * ((th - 90) / 65) ** 2, 30.0)
    a_h = -min(12 * (rel_az_deg / 65) ** 2, 30.0)
    a = 8.0 - min(-(a_v + a_h), 30.0)
    ks = np.arange(m) - (m - 1) / 2
    af = np.sum(np.exp(1j * 2 * np.pi * ks * d * (np.cos(zen) - np.cos(math.radians(tilt_deg)))))
    return math.sqrt(10 ** (a / 10)) * af / math.sqrt(m)


def test_one_los_path_gets_the_sector_gain_and_the_right_sector():
    # site at 25 m, UE 1.5 m high 200 m away at azimuth 200 deg: zenith 90 + atan(23.5/200)
    zen = math.pi / 2 + math.atan2(23.5, 200.0)
    az = math.radians(200.0)
    # boresights 90, 210, 330 deg: the 210 deg sector is 10 deg off, the others 110 / 130 deg
    bore = sector_boresights(np.array([math.radians(90.0)]), 3)
    panel = SectorPanel()
    cir = _cir([[az]], [[zen]], [[1e-5]], [0])
    out, sector = apply_sectors(cir, panel, bore)
    assert sector.tolist() == [[1]]
    expect = _expected_field(zen, -10.0)
    np.testing.assert_allclose(out.gains, cir.gains * expect, rtol=RTOL)
    # nothing but the gains changes
    for name in ("delays", "aod_az", "aod_zen", "valid", "tx_index", "los"):
        np.testing.assert_array_equal(getattr(out, name), getattr(cir, name))


def test_strongest_sector_wins_over_paths_and_empty_slots_stay():
    zen = math.radians(95.0)
    bore = sector_boresights(np.array([0.0, math.radians(30.0)]), 3)   # sites 0 and 1
    # slot 0 (site 0): a weak path at 5 deg (sector 0) and a 10x stronger one at 235 deg
    # (sector 2 at 240 deg, 5 deg off): the link takes sector 2 and applies it to both paths;
    # slot 1 (site 1, boresights 30/150/270): one path at 150 deg -> sector 1; slot 2 empty
    aod = [[math.radians(5.0), math.radians(235.0)], [math.radians(150.0), 0.0], [0.0, 0.0]]
    amp = [[1e-6, 1e-5], [1e-5, 0.0], [0.0, 0.0]]
    cir = _cir(aod, np.full((3, 2), zen), amp, [0, 1, NO_TX])
    out, sector = apply_sectors(cir, SectorPanel(), bore)
    assert sector.tolist() == [[2, 1, -1]]
    f_weak, f_strong = _expected_field(zen, 5.0 - 240.0 + 360.0), _expected_field(zen, -5.0)
    np.testing.assert_allclose(out.gains[0, 0, :, 0], cir.gains[0, 0, :, 0] * f_weak, rtol=RTOL)
    np.testing.assert_allclose(out.gains[0, 0, :, 1], cir.gains[0, 0, :, 1] * f_strong,
                               rtol=RTOL)
    np.testing.assert_allclose(out.gains[0, 1, :, 0], cir.gains[0, 1, :, 0]
                               * _expected_field(zen, 0.0), rtol=RTOL)
    np.testing.assert_array_equal(out.gains[0, 2], cir.gains[0, 2])


def test_default_config_leaves_the_links_bit_for_bit():
    cir = _cir([[0.4]], [[1.7]], [[1e-5]], [0])
    prop = Propagation(bs_ue=cir, bs_adv=cir, adv_ue=cir, stats={"x": 1})

    class Geo:
        bs_pos = np.zeros((1, 3))
        bs_azimuth = None
        layout = None

    assert TopologyConfig().bs_antenna == "isotropic"
    assert apply_bs_antenna(prop, Geo(), TopologyConfig()) is prop
    # 'tr38901' changes the links that leave a BS, not the adversary's own
    out = apply_bs_antenna(prop, Geo(), TopologyConfig(bs_antenna="tr38901"))
    assert out.adv_ue is cir and not np.array_equal(out.bs_ue.gains, cir.gains)
    np.testing.assert_array_equal(out.bs_ue.gains, out.bs_adv.gains)
    # no layout, no azimuths: Table 7.8-1's 30 / 150 / 270 deg; 0.4 rad = 22.9 deg -> the first
    assert out.stats["bs_antenna"]["bs_ue_links_per_sector"] == [1, 0, 0]
    # the link's gain: |field|^2 towards (97.4 deg, 22.9 - 30 deg), stored to 0.001 dB
    gain = 10 * math.log10(abs(_expected_field(1.7, math.degrees(0.4) - 30.0)) ** 2)
    assert out.stats["bs_antenna"]["link_gain_db"]["p50"] == pytest.approx(gain, abs=5e-4)


# -- both arms: the stochastic links carry departure angles, the run applies the panels -------
def _uma_run_links(tmp_path, mode, topology):
    from veriloc_rt.config import config_from_dict
    from veriloc_rt.propagation.stochastic import stochastic_propagation
    from veriloc_rt.sim.engine import compute_propagation
    from veriloc_rt.world.geometry import build_geometry

    cfg = config_from_dict({"trajectory": {"num_points": 12}, "topology": topology,
                            "run": {"scenarios": ["none", "fbs"]},
                            "propagation": {"model": "uma", "uma_mode": mode}})
    geo = build_geometry(cfg, tmp_path)
    iso = stochastic_propagation(geo, cfg.propagation, cfg.seed)
    return geo, iso, compute_propagation(cfg, geo, cache_dir=None)


def test_pathloss_only_departs_along_the_line_of_sight(tmp_path):
    geo, iso, _ = _uma_run_links(tmp_path, "pathloss_only", {})
    d = iso.bs_ue.rx_pos[:, None, :] - iso.bs_ue.tx_pos          # BS -> UE
    az = np.arctan2(d[..., 1], d[..., 0])
    zen = np.arccos(d[..., 2] / np.linalg.norm(d, axis=-1))
    np.testing.assert_allclose(iso.bs_ue.aod_az[..., 0], az, rtol=0, atol=1e-12)
    np.testing.assert_allclose(iso.bs_ue.aod_zen[..., 0], zen, rtol=0, atol=1e-12)


@pytest.mark.parametrize("mode", ["pathloss_only", "fast_fading"])
def test_run_applies_the_panels_to_the_stochastic_arm(tmp_path, mode):
    # default: the run's links are the model's, bit for bit
    geo, iso, run = _uma_run_links(tmp_path / "a", mode, {})
    for name in ("bs_ue", "bs_adv", "adv_ue"):
        assert np.array_equal(getattr(run, name).gains, getattr(iso, name).gains)
    # tr38901: each BS -> UE path times the field of the site's strongest sector, recomputed
    # here path by path from the hexagonal layout's boresights (90 / 210 / 330 deg + rotation)
    geo, iso, run = _uma_run_links(tmp_path / "b", mode, {"bs_antenna": "tr38901"})
    assert np.array_equal(run.adv_ue.gains, iso.adv_ue.gains)
    cir = iso.bs_ue
    rot = math.degrees(geo.layout.rotation)
    for k in range(cir.num_points):
        for j in range(cir.num_tx):
            paths = np.flatnonzero(cir.valid[k, j])
            best, best_power, best_field = None, -1.0, None
            for s, bore in enumerate((90.0 + rot, 210.0 + rot, 330.0 + rot)):
                f = np.array([_expected_field(cir.aod_zen[k, j, n],
                                              (math.degrees(cir.aod_az[k, j, n]) - bore + 180)
                                              % 360 - 180) for n in paths])
                power = np.sum(np.abs(f) ** 2 * np.mean(np.abs(cir.gains[k, j][:, paths]) ** 2, 0))
                if power > best_power:
                    best, best_power, best_field = s, power, f
            np.testing.assert_allclose(run.bs_ue.gains[k, j][:, paths],
                                       cir.gains[k, j][:, paths] * best_field[None], rtol=1e-9)
    assert run.stats["bs_antenna"]["model"] == "tr38901"


def test_link_budget_names_the_bs_antennas():
    from veriloc_rt.report.link_budget import format_link_budget, link_budget_block

    links = {"index": np.array([0, 0]), "rx_power_dbm": np.array([-90.0, -95.0]),
             "snr_re_db": np.array([3.0, -2.0]), "heard": np.array([True, True]),
             "tag_verified": np.array([True, False]), "used": np.array([True, True])}
    name = describe_bs_antenna(TopologyConfig(bs_antenna="tr38901"))
    block = link_budget_block(links, 5, 4.3, bs_antenna=name)
    assert block["bs_antenna"] == name
    assert format_link_budget(block).endswith(f"; BS antenna {name}")
    assert "BS antenna" not in format_link_budget(link_budget_block(links, 5, 4.3))


@pytest.mark.raytrace
def test_traced_departure_angles_point_along_the_line_of_sight(tmp_path):
    """The traced arm's departure angles are the panels' input: a LoS link's direct path leaves
    its transmitter towards the receiver (float32 tracing: 1e-4 rad)."""
    from veriloc_rt.config import config_from_dict
    from veriloc_rt.propagation.raytrace import trace
    from veriloc_rt.world.geometry import build_geometry

    cfg = config_from_dict({"seed": 3, "scene": {"extent_m": 140.0, "margin_m": 30.0},
                            "trajectory": {"num_points": 14, "region_m": 70.0},
                            "propagation": {"raytrace": {"rays_per_source": 3000,
                                                         "max_depth": 2}}})
    geo = build_geometry(cfg, tmp_path / "scene")
    prop = trace(geo, cfg.propagation, cfg.seed, cache_dir=None)
    checked = 0
    for cir in (prop.bs_ue, prop.adv_ue):
        d = np.where(cir.valid, cir.delays, np.inf)
        first = np.argmin(d, axis=-1)
        for k, j in zip(*np.nonzero(cir.los & cir.has_path())):
            n = first[k, j]
            v = cir.rx_pos[k] - cir.tx_pos[k, j]
            az, zen = math.atan2(v[1], v[0]), math.acos(v[2] / np.linalg.norm(v))
            assert abs((cir.aod_az[k, j, n] - az + np.pi) % (2 * np.pi) - np.pi) < 1e-4
            assert abs(cir.aod_zen[k, j, n] - zen) < 1e-4
            checked += 1
    assert checked > 0


def test_traced_power_selection_ranks_the_candidates_through_the_panels(tmp_path, monkeypatch):
    """'traced_power' chooses the strongest candidates after the panels: a fake traced model
    gives each (point, site) one path of known power leaving at a site-dependent azimuth, and
    the chosen TRPs must be the top ones by power x |field|^2, recomputed here."""
    from veriloc_rt.config import config_from_dict
    from veriloc_rt.sim import engine
    from veriloc_rt.world.geometry import Geometry
    from veriloc_rt.world.sites import candidate_sites
    from veriloc_rt.world.trajectory import Trajectory

    zen = math.radians(95.0)

    def power(k, b):
        return 1e-9 * (1.0 + (b * 7 + k * 3) % 5)

    def azimuth(k, b):                       # degrees: off the 30/150/270 boresights by 0-57
        return 30.0 + 19.0 * ((b + 2 * k) % 4)

    class Fake:
        def __call__(self, geometry, cfg, seed, *, progress=None, cache_dir="default",
                     adversary_points=None, workers=1, ue_points=None):
            P, T = geometry.serving.shape
            k = np.arange(P)[:, None]
            b = geometry.serving
            az = np.radians(azimuth(k, b))[..., None]
            c = CIR(delays=np.full((P, T, 1), 1e-6),
                    gains=np.sqrt(power(k, b))[:, :, None, None].astype(complex),
                    aoa_az=np.zeros((P, T, 1)), aoa_zen=np.zeros((P, T, 1)), aod_az=az,
                    aod_zen=np.full((P, T, 1), zen), doppler=np.zeros((P, T, 1)),
                    interactions=np.zeros((P, T, 1, 1), np.uint8),
                    valid=np.ones((P, T, 1), bool), tx_index=b, tx_pos=np.zeros((P, T, 3)),
                    rx_pos=np.zeros((P, 3)), los=np.zeros((P, T), bool),
                    carrier_frequency=3.5e9)
            adv = dataclasses.replace(c, delays=c.delays[:, :1], gains=c.gains[:, :1],
                                      aoa_az=c.aoa_az[:, :1], aoa_zen=c.aoa_zen[:, :1],
                                      aod_az=c.aod_az[:, :1], aod_zen=c.aod_zen[:, :1],
                                      doppler=c.doppler[:, :1], valid=c.valid[:, :1],
                                      interactions=c.interactions[:, :1],
                                      tx_index=np.full((P, 1), -2), tx_pos=c.tx_pos[:, :1],
                                      los=c.los[:, :1])
            return Propagation(bs_ue=c, bs_adv=c, adv_ue=adv, stats={"links": P * T})

    class Registry:
        def get(self, name):
            return Fake

    xs = np.arange(5) * 80.0
    sites = np.array([[x, y, 10.0] for x in xs for y in xs])
    csv = tmp_path / "s.csv"
    csv.write_text("x,y,z\n" + "".join(f"{x},{y},{z}\n" for x, y, z in sites))
    cfg = config_from_dict({"topology": {"selection": "traced_power", "sites": str(csv),
                                         "num_trps": 3, "candidate_radius_m": 130.0,
                                         "bs_antenna": "tr38901"},
                            "propagation": {"model": "raytrace"}, "run": {"scenarios": ["none"]}})
    P = 10
    pos = np.concatenate([np.random.default_rng(4).uniform(0, 320, (P, 2)), np.full((P, 1), 1.5)],
                         axis=1)
    ue = Trajectory(np.arange(P, dtype=float), pos, np.zeros((P, 3)), np.arange(P, dtype=float),
                    pos)
    bs, serving, cand, _ = candidate_sites(sites, pos[:, :2], 3, 130.0)
    geo = Geometry(scene_xml=tmp_path / "x.xml", scene=None, full_canyon=None, layout=None,
                   bs_pos=bs, serving=serving, ue=ue, adversary=ue, candidates=cand,
                   bs_azimuth=np.full(len(bs), np.nan))
    monkeypatch.setattr(engine, "PROPAGATION_REGISTRY", Registry())
    chosen, prop = engine.traced_power_serving(cfg, geo)

    def through_panel(k, b):                 # the best of the 30/150/270 deg sectors
        f = max(abs(_expected_field(zen, (azimuth(k, b) - bo + 180) % 360 - 180)) ** 2
                for bo in (30.0, 150.0, 270.0))
        return power(k, b) * f

    differs = False
    for k in range(P):
        valid = [int(c) for c in cand[k] if c >= 0]
        expect = sorted(valid, key=lambda b: (-through_panel(k, b), valid.index(b)))[:3]
        assert list(chosen.serving[k]) == expect
        iso = sorted(valid, key=lambda b: (-power(k, b), valid.index(b)))[:3]
        differs |= iso != expect
    assert differs          # the panels changed the choice somewhere: the test can tell
    got = prop.bs_ue.path_power().sum(-1)
    want = [[through_panel(k, b) for b in chosen.serving[k]] for k in range(P)]
    np.testing.assert_allclose(got, want, rtol=1e-9)
