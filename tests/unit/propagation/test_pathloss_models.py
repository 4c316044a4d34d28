"""Published path-loss models: worked values derived term by term, and an independent reference.

Origin of the reference values:
* ``*_by_hand``: each term written out from the formula text (P.525-4; COST 231 final report
  ch. 4.4; P.1411 sec. 4.2.2.1; TR 38.901 Table 7.4.1-1) and evaluated with Python's math module
  (log10, sqrt, atan, tanh), not with the code under test; the intermediate numbers are in the
  comments, rounded to 4-6 decimals, and the asserted totals are their sums.
* NS3_REFERENCE: the expected values of ns-3's test suite "itu-r-1411-nlos-over-rooftop"
  (src/propagation/test/), printed to 0.01 dB. ns-3 ships an independent Octave implementation
  of the model next to it (test/reference/loss_ITU1411_NLOS_over_rooftop.m); the values follow
  from it with ns-3's default scene (roofs 20 m, w 20 m, phi 45 deg, b 50 m, l 80 m) and d the
  2-D distance. Both cases have l < d_s (the L2_msd, Q_M regime), where ns-3's older edition and
  the newer tanh blend agree once d is well past d_bp.
"""

import math

import numpy as np
import pytest

from veriloc_rt.propagation.pathloss_models import (RooftopGeometry, cost231_wi_nlos_db,
                                                    cost231_wi_terms, free_space_pathloss_db,
                                                    p1411_nlos_db, p1411_terms,
                                                    street_orientation_loss_db, umi_pathloss_db,
                                                    validity_flags)

#: hand-derived terms are printed to 4-6 significant decimals; their sums carry < 1e-3 dB
TOL_HAND_DB = 1e-3
#: ns-3's reference is printed to 0.01 dB (half a unit of the last digit)
TOL_NS3_PRINT_DB = 0.005
#: TR 38.901 writes c = 3e8 m/s in d'BP; the code uses 299 792 458: < 0.006 dB here
TOL_C_CONVENTION_DB = 0.01

SCENE = RooftopGeometry(h_bs_m=25.0, h_ue_m=1.5, h_roof_m=15.0, street_width_m=5.0,
                        building_separation_m=35.0)


def test_free_space_by_hand():
    # P.525-4: 20 lg(4 pi d f / c). d = 1 km, f = 1 MHz: 4 pi 1e9 / c = 41.916900,
    # 20 lg 41.916900 = 32.44778 (the "32.4" P.525 prints, unrounded)
    assert free_space_pathloss_db(1000.0, 1e6) == pytest.approx(32.44778, abs=TOL_HAND_DB)
    # d = 200 m, 3.5 GHz: 32.44778 + 20 lg 3500 (70.88136) + 20 lg 0.2 (-13.97940) = 89.34974
    assert free_space_pathloss_db(200.0, 3.5e9) == pytest.approx(89.34974, abs=TOL_HAND_DB)


@pytest.mark.parametrize("phi_deg, expect", [
    (0.0, -10.0),                  # -10 + 0.354 * 0
    (30.0, 0.62),                  # -10 + 0.354 * 30
    (45.0, 3.25),                  # 2.5 + 0.075 * (45 - 35)
    (55.0, 4.0),                   # 4.0 - 0.114 * 0
    (90.0, 0.01),                  # 4.0 - 0.114 * 35
])
def test_street_orientation_term_by_hand(phi_deg, expect):
    assert street_orientation_loss_db(math.radians(phi_deg)) == pytest.approx(expect, abs=1e-9)


def test_cost231_above_roofs_by_hand():
    # f 1800 MHz, d 1 km, h_Base 30 m, h_Roof 20 m (dh_Base 10), h_Mobile 1.5 m (dh_Mobile 18.5),
    # w 15 m, b 30 m, phi 90 deg, medium-sized city.
    # L_0 = 32.4 + 20 lg 1 + 20 lg 1800 (65.10545) = 97.50545
    # L_ori = 4.0 - 0.114 * 35 = 0.01
    # L_rts = -16.9 - 10 lg 15 (11.76091) + 10 lg 1800 (32.55273) + 20 lg 18.5 (25.34343) + 0.01
    #       = 29.24525
    # L_bsh = -18 lg 11 = -18.74507; k_a = 54; k_d = 18 (18 lg 1 = 0)
    # k_f = -4 + 0.7 (1800/925 - 1) = -3.337838; k_f lg 1800 = -10.86557; -9 lg 30 = -13.29409
    # L_msd = -18.74507 + 54 + 0 - 10.86557 - 13.29409 = 11.09527
    # L_b = 97.50545 + 29.24525 + 11.09527 = 137.84597
    geo = RooftopGeometry(30.0, 1.5, 20.0, 15.0, 30.0)
    t = cost231_wi_terms(1000.0, 1.8e9, geo, math.pi / 2)
    assert t["L_bf"] == pytest.approx(97.50545, abs=TOL_HAND_DB)
    assert t["L_rts"] == pytest.approx(29.24525, abs=TOL_HAND_DB)
    assert t["k_f"] == pytest.approx(-3.337838, abs=1e-6)
    assert t["L_msd"] == pytest.approx(11.09527, abs=TOL_HAND_DB)
    assert cost231_wi_nlos_db(1000.0, 1.8e9, geo, math.pi / 2) == pytest.approx(137.84597,
                                                                                abs=TOL_HAND_DB)


def test_cost231_below_roofs_short_range_by_hand():
    # f 900 MHz, d 400 m (< 500 m), h_Base 15 m below h_Roof 20 m (dh_Base -5), h_Mobile 1.5 m,
    # w 15 m, b 30 m, phi 30 deg.
    # L_0 = 32.4 + 20 lg 0.4 (-7.95880) + 20 lg 900 (59.08485) = 83.52605
    # L_rts = -16.9 - 11.76091 + 10 lg 900 (29.54243) + 25.34343 + (-10 + 0.354*30 = 0.62)
    #       = 26.84495
    # L_bsh = 0; k_a = 54 - 0.8 (-5) (0.4 / 0.5) = 57.2; k_d = 18 - 15 (-5) / 20 = 21.75
    # k_d lg 0.4 = -8.65520; k_f = -4 + 0.7 (900/925 - 1) = -4.018919, k_f lg 900 = -11.87286
    # L_msd = 57.2 - 8.65520 - 11.87286 - 13.29409 = 23.37785
    # L_b = 83.52605 + 26.84495 + 23.37785 = 133.74885
    geo = RooftopGeometry(15.0, 1.5, 20.0, 15.0, 30.0)
    t = cost231_wi_terms(400.0, 0.9e9, geo, math.radians(30.0))
    assert float(t["k_a"]) == pytest.approx(57.2, abs=1e-9)
    assert float(t["k_d"]) == pytest.approx(21.75, abs=1e-9)
    assert t["L_msd"] == pytest.approx(23.37785, abs=TOL_HAND_DB)
    assert t["total"] == pytest.approx(133.74885, abs=TOL_HAND_DB)


def test_p1411_settled_field_on_the_canyon_by_hand():
    # The default canyon: f 3.5 GHz (lambda = 0.0856550 m), d = l = 200 m, h_b 25, h_r 15
    # (dh_b 10), h_m 1.5 (dh_m 13.5), w 5, b 35, phi 90 deg.
    # d_s = lambda d^2 / dh_b^2 = 34.262 m < l: settled field; d_bp = 10 sqrt(200/lambda) = 483.213
    # L_bf = 32.4 - 13.97940 + 70.88136 = 89.30196
    # L_rts = -8.2 - 6.98970 + 35.44068 + 22.60668 + 0.01 = 42.86766
    # L1_msd(d) = -18 lg 11 (-18.74507) + 71.4 + 18 lg 0.2 (-12.58146) - 8 lg 3500 (-28.35254)
    #             - 9 lg 35 (-13.89661) = -2.17569
    # L_upp = L1_msd(483.213) = -2.17569 + 12.58146 + 18 lg 0.483213 (-5.68550) = 4.72027
    # L_low = -20 lg(2.35 (10/483.213 sqrt(35/lambda) = 0.418330)^0.9 = 1.072593) = -0.60870
    # L_mid = 2.05579; tanh((lg 200 - lg 483.213) / 0.1 = -3.831087) = -0.999060
    # L_msd = 0.999060 (-2.17569 - 2.05579) + 2.05579 = -2.17171
    # L = 89.30196 + 42.86766 - 2.17171 = 129.99791
    t = p1411_terms(200.0, 3.5e9, SCENE, math.pi / 2, 200.0)
    assert t["d_s"] == pytest.approx(34.262, abs=1e-3)
    assert t["d_bp"] == pytest.approx(483.213, abs=1e-3)
    assert t["L_rts"] == pytest.approx(42.86766, abs=TOL_HAND_DB)
    assert t["L1_msd"] == pytest.approx(-2.17569, abs=TOL_HAND_DB)
    assert t["L_upp"] == pytest.approx(4.72027, abs=TOL_HAND_DB)
    assert t["L_low"] == pytest.approx(-0.60870, abs=TOL_HAND_DB)
    assert t["L_msd"] == pytest.approx(-2.17171, abs=TOL_HAND_DB)
    assert p1411_nlos_db(200.0, 3.5e9, SCENE, math.pi / 2) == pytest.approx(129.99791,
                                                                            abs=TOL_HAND_DB)


def test_p1411_bs_below_roofs_negative_dh_bp_by_hand():
    # h_b 10 m below the 15 m roofs (dh_b -5), d = l = 1000 m, f 3.5 GHz, w 5, b 35, phi 90:
    # d_s = lambda 1e6 / 25 = 3426.2 m > l (near grazing); d_bp = 5 sqrt(1000/lambda) = 540.249
    # h_b < h_r + dh_l (dh_l = -15.61055 / (lg 3500)^2.938 (41.15637) + 0.02734 + 0.06923
    # = -0.28273): Q_M = b/(2 pi d) sqrt(lambda/rho) (1/theta - 1/(2 pi + theta)),
    # theta = atan(-5/35) = -0.141897, rho = 35.35534, sqrt(lambda/rho) = 0.0492208,
    # (1/theta - 1/(2 pi + theta)) = -7.210195 -> Q_M = -0.00197690, L2_msd(d) = 54.08032
    # L_upp = L1_msd(540.249): k_a = 73 - 0.8 (-5) = 77, k_d = 18 - 15 (-5)/15 = 23,
    #   77 + 23 lg 0.540249 (-6.15142) - 28.35254 - 13.89661 = 28.60050 (L_bsh = 0)
    # L_low = L2_msd(540.249) = 48.73219; dh_bp = -20.13170 < 0, zeta = 0.0417 dh_bp = -0.839492
    # L_mid = 38.66635; tanh(lg(1000/540.249) = 0.267406 / zeta) = -0.308180
    # L_msd = 54.08032 + (-0.308180)(38.66635 - 48.73219) + 38.66635 - 48.73219 = 47.11657
    # L = L_bf (103.28136) + L_rts (42.86766) + 47.11657 = 193.26559
    geo = RooftopGeometry(10.0, 1.5, 15.0, 5.0, 35.0)
    t = p1411_terms(1000.0, 3.5e9, geo, math.pi / 2, 1000.0)
    assert t["L2_msd"] == pytest.approx(54.08032, abs=TOL_HAND_DB)
    assert t["L_upp"] == pytest.approx(28.60050, abs=TOL_HAND_DB)
    assert t["L_low"] == pytest.approx(48.73219, abs=TOL_HAND_DB)
    assert t["L_msd"] == pytest.approx(47.11657, abs=TOL_HAND_DB)
    assert t["total"] == pytest.approx(193.26559, abs=TOL_HAND_DB)


# f (Hz), d (m), reference loss (dB), tolerance: print rounding plus the edition difference, the
# tanh blend's residual (1 - tanh((lg d - lg d_bp)/0.1)) |L2_msd - L_mid|: 1.6e-4 dB at 900 m
# (d/d_bp = 3.79), 0.0086 dB at 500 m (d/d_bp = 2.24)
NS3_REFERENCE = [(2.114e9, 900.0, 143.68, TOL_NS3_PRINT_DB + 2e-4),
                 (1.865e9, 500.0, 132.84, TOL_NS3_PRINT_DB + 0.0087)]


@pytest.mark.parametrize("fc, d, expect, tol", NS3_REFERENCE)
def test_p1411_against_ns3_reference(fc, d, expect, tol):
    geo = RooftopGeometry(h_bs_m=30.0, h_ue_m=1.0, h_roof_m=20.0, street_width_m=20.0,
                          building_separation_m=50.0)
    assert p1411_nlos_db(d, fc, geo, math.radians(45.0), 80.0) == pytest.approx(expect, abs=tol)


def test_p1411_q_m_is_continuous_where_its_first_two_forms_meet():
    # P.1411: dh_u = 10^(-lg sqrt(b/lambda) - lg(d)/9 + (10/9) lg(b/2.35)) solves
    # 2.35 (dh_u/d sqrt(b/lambda))^0.9 = b/d; for d = 300 m, b = 35 m, 3.5 GHz: 0.527764 m.
    # Just above h_r + dh_u Q_M uses the first form, just below the second: same L2_msd.
    d, dh_u, eps = 300.0, 0.527764, 1e-5
    above = RooftopGeometry(15.0 + dh_u + eps, 1.5, 15.0, 5.0, 35.0)
    below = RooftopGeometry(15.0 + dh_u - eps, 1.5, 15.0, 5.0, 35.0)
    l_above = p1411_terms(d, 3.5e9, above, 0.0)["L2_msd"]
    l_below = p1411_terms(d, 3.5e9, below, 0.0)["L2_msd"]
    assert l_below == pytest.approx(-20 * math.log10(35.0 / d), abs=1e-9)   # b/d
    # the first form's slope is 20 * 0.9 / ln(10) / dh_u = 14.8 dB/m: eps moves it 1.5e-4 dB
    assert l_above == pytest.approx(l_below, abs=3e-4)


def test_p1411_msd_is_continuous_at_the_breakpoint():
    # At d = d_bp both blends give L_mid = (L_upp + L_low)/2 (tanh 0 = 0): approach from both sides
    lam = 299_792_458.0 / 3.5e9
    ell = 200.0
    d_bp = 10.0 * math.sqrt(ell / lam)
    lo = p1411_terms(d_bp * (1 - 1e-7), 3.5e9, SCENE, 0.3, ell)
    hi = p1411_terms(d_bp * (1 + 1e-7), 3.5e9, SCENE, 0.3, ell)
    assert lo["L_msd"] == pytest.approx(0.5 * (lo["L_upp"] + lo["L_low"]), abs=1e-4)
    assert hi["L_msd"] == pytest.approx(lo["L_msd"], abs=1e-4)


def test_umi_nlos_and_los_by_hand():
    # d2D 200 m, h_BS 10, h_UT 1.5, 3.5 GHz: d3D = 200.18054 (lg 2.301422);
    # d'BP = 4 * 9 * 0.5 * 3.5e9 / c = 210.145 m > d2D: PL1 = 32.4 + 48.32986 + 10.88136 = 91.61122
    # PL'_NLOS = 22.4 + 35.3 lg d3D (81.24019) + 21.3 lg 3.5 (11.58865) = 115.22884 > PL1
    assert umi_pathloss_db(200.0, 10.0, 1.5, 3.5e9, False) == pytest.approx(115.22884,
                                                                            abs=TOL_HAND_DB)
    assert umi_pathloss_db(200.0, 10.0, 1.5, 3.5e9, True) == pytest.approx(91.61122,
                                                                           abs=TOL_HAND_DB)
    # d2D 1000 m > d'BP: PL2 = 32.4 + 40 lg 1000.0361 (120.00063) + 10.88136
    #   - 9.5 lg(210.0^2 + 8.5^2) (-44.12892, the spec's c = 3e8) = 119.15307
    assert umi_pathloss_db(1000.0, 10.0, 1.5, 3.5e9, True) == pytest.approx(
        119.15307, abs=TOL_C_CONVENTION_DB)


def test_validity_flags_say_what_is_outside():
    assert validity_flags("cost231_wi", 3.5e9, 25.0, 1.5) == ["f = 3.5 GHz > 2 GHz"]
    assert validity_flags("cost231_wi", 1.8e9, 25.0, 1.5) == []
    assert validity_flags("p1411", 3.5e9, 25.0, 1.5, [10.0, 50.0, 6000.0]) == [
        "1 of 3 links at d < 20 m", "1 of 3 links at d > 5000 m"]
    assert validity_flags("umi_nlos", 3.5e9, 25.0, 1.5) == ["h_BS = 25 m, the model's is 10 m"]
    assert validity_flags("uma_nlos", 3.5e9, 25.0, 1.5) == []
    assert validity_flags("free_space", 3.5e9, 25.0, 1.5, [1.0]) == []
    with pytest.raises(ValueError, match="`model`"):
        validity_flags("hata", 3.5e9, 25.0, 1.5)


def test_models_take_arrays_and_reject_bad_arguments():
    d = np.array([100.0, 400.0])
    phi = np.radians([10.0, 80.0])
    arr = p1411_nlos_db(d, 3.5e9, SCENE, phi)
    assert arr.shape == (2,) and arr[1] == p1411_nlos_db(400.0, 3.5e9, SCENE, phi[1])
    assert cost231_wi_nlos_db(d, 3.5e9, SCENE, phi).shape == (2,)
    with pytest.raises(ValueError, match="`d_m`"):
        p1411_nlos_db(0.0, 3.5e9, SCENE, 0.0)
    with pytest.raises(ValueError, match="`phi_rad`"):
        cost231_wi_nlos_db(100.0, 3.5e9, SCENE, 2.0)
    with pytest.raises(ValueError, match="`h_ue_m`"):
        RooftopGeometry(25.0, 16.0, 15.0, 5.0, 35.0)
