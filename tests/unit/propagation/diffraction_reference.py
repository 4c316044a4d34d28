"""Independent references for edge diffraction, in NumPy (float64), for the tests.

Nothing here is shared with the package: the formulas are written from the literature.

* The exact solution of a perfectly conducting half-plane lit by a plane wave (Sommerfeld 1896),
  in the form of Balanis, *Advanced Engineering Electromagnetics*, 2nd ed., Sec. 13.3.1,
  eqs. (13-35)-(13-37) (e^{+j w t} time convention, fields e^{-j k r}):

      u_total = V(rho, phi - phi') -+ V(rho, phi + phi'),
      V(rho, b) = e^{j k rho cos b} F_S(-sqrt(2 k rho) cos(b / 2)),
      F_S(x) = e^{j pi/4} / sqrt(pi) * int_x^inf e^{-j t^2} dt,

  with '-' for the soft case (E parallel to the edge, Dirichlet) and '+' for the hard case
  (H parallel to the edge, Neumann). phi, phi' are measured from the lit face, 0 < phi < 2 pi.
* The uniform theory of diffraction (UTD) of Kouyoumjian and Pathak, "A uniform geometrical
  theory of diffraction for an edge in a perfectly conducting surface", Proc. IEEE 62(11),
  1974, eqs. (25)-(31): the four cotangent terms D1..D4 with the transition function
  F(X) = 2 j sqrt(X) e^{jX} int_{sqrt X}^inf e^{-j t^2} dt and a^{+-}(b) = 2 cos^2((2 n pi N - b) / 2).
* Luebbers' heuristic for a lossy wedge, "Finite conductivity uniform GTD versus knife edge
  diffraction in prediction of propagation path loss", IEEE Trans. AP-32(1), 1984, eq. (6):
  D = D1 + D2 + R_n D3 + R_0 D4, with R_0 evaluated at the grazing angle phi' on the 0-face and
  R_n at n pi - phi on the n-face, soft with the TE (perpendicular) and hard with the TM
  (parallel) Fresnel coefficient.
* The Fresnel coefficients of a slab, ITU-R P.2040-3 eqs. (37), (43), (44), with the material
  model of its Table 3.
"""

from __future__ import annotations

import numpy as np
from scipy.special import fresnel as _fresnel_cs

EPS0 = 8.8541878128e-12
#: ITU-R P.2040-3 Table 3: a, b, c, d of eta' = a f^b, sigma = c f^d (f in GHz)
ITU_P2040 = {"concrete": (5.24, 0.0, 0.0462, 0.7822),
             "metal": (1.0, 0.0, 1e7, 0.0),
             "medium_dry_ground": (15.0, -0.1, 0.035, 1.63)}


def int_exp_tail(x):
    """int_x^inf e^{-j t^2} dt for real x (any sign), via the Fresnel integrals C and S."""
    x = np.asarray(x, float)
    s, c = _fresnel_cs(x * np.sqrt(2.0 / np.pi))      # int_0^z cos / sin(pi t^2 / 2)
    return np.sqrt(np.pi / 2.0) * ((0.5 - c) - 1j * (0.5 - s))


def sommerfeld_half_plane(rho, phi, phi_p, k, soft: bool):
    """Total and diffracted field of a PEC half-plane lit by a unit plane wave.

    The incident wave is e^{j k rho cos(phi - phi')} (unit amplitude at the edge).
    :returns: (total, diffracted) complex, diffracted = total - geometrical optics
    """
    sign = -1.0 if soft else 1.0

    def v(b):
        return np.exp(1j * k * rho * np.cos(b)) * np.exp(1j * np.pi / 4) / np.sqrt(np.pi) \
            * int_exp_tail(-np.sqrt(2 * k * rho) * np.cos(b / 2))

    total = v(phi - phi_p) + sign * v(phi + phi_p)
    go = np.exp(1j * k * rho * np.cos(phi - phi_p)) * (abs(phi - phi_p) < np.pi) \
        + sign * np.exp(1j * k * rho * np.cos(phi + phi_p)) * (phi + phi_p < np.pi)
    return total, total - go


def transition(x):
    """Kouyoumjian-Pathak transition function F(X), X >= 0."""
    x = np.asarray(x, float)
    sx = np.sqrt(x)
    return 2j * sx * np.exp(1j * x) * int_exp_tail(sx)


def _a(beta, n, sign):
    """a^{+-}(beta) with N the integer most nearly satisfying 2 pi n N - beta = +-pi."""
    big_n = np.round((beta + sign * np.pi) / (2 * np.pi * n))
    return 2 * np.cos((2 * np.pi * n * big_n - beta) / 2) ** 2


def kp_terms(phi, phi_p, beta0, n, k, big_l):
    """The four UTD terms D1..D4 (Kouyoumjian-Pathak eq. (25)), each with the common factor.

    :param phi, phi_p: diffraction and incidence angles from the 0-face [rad]
    :param beta0: angle between the incident ray and the edge [rad]
    :param n: exterior wedge angle / pi
    :param big_l: distance parameter L [m]
    """
    c = -np.exp(-1j * np.pi / 4) / (2 * n * np.sqrt(2 * np.pi * k) * np.sin(beta0))
    dm, dp = phi - phi_p, phi + phi_p

    def term(num, beta, sign):
        return c / np.tan((np.pi + sign * beta) / (2 * n)) * transition(k * big_l * _a(beta, n, sign))

    return term(1, dm, +1), term(2, dm, -1), term(3, dp, +1), term(4, dp, -1)


def kp_soft_hard(phi, phi_p, beta0, n, k, big_l, r0=(-1.0, 1.0), rn=(-1.0, 1.0)):
    """(D_s, D_h): Kouyoumjian-Pathak for a PEC wedge (default reflection coefficients
    R = -1 soft, +1 hard) or Luebbers' heuristic with the faces' (R_soft, R_hard)."""
    d1, d2, d3, d4 = kp_terms(phi, phi_p, beta0, n, k, big_l)
    return (d1 + d2 + rn[0] * d3 + r0[0] * d4, d1 + d2 + rn[1] * d3 + r0[1] * d4)


def permittivity(material: str, fc: float) -> complex:
    """Complex relative permittivity, ITU-R P.2040-3 eqs. (9a), (9b) and Table 3."""
    a, b, c, d = ITU_P2040[material]
    f_ghz = fc / 1e9
    return a * f_ghz ** b - 1j * c * f_ghz ** d / (2 * np.pi * fc * EPS0)


def slab_reflection(eta: complex, cos_i: float, thickness: float, wavelength: float):
    """(R_TE, R_TM) of a slab in vacuum, ITU-R P.2040-3 eqs. (37), (43a), (44)."""
    root = np.sqrt(eta - (1 - cos_i ** 2) + 0j)
    r_te = (cos_i - root) / (cos_i + root)
    r_tm = (eta * cos_i - root) / (eta * cos_i + root)
    q = 2 * np.pi * thickness / wavelength * root
    e2 = np.exp(-2j * q)
    return tuple(r * (1 - e2) / (1 - r ** 2 * e2) for r in (r_te, r_tm))
