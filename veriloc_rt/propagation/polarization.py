"""Antenna polarization applied to polarimetric ray-traced paths, and material depolarization.

The tracer gives every path its 2x2 polarimetric coefficient ``A`` in the spherical bases of the
two ends: row = receive port, column = transmit port, port 0 = theta-hat, port 1 = phi-hat
(Sionna RT's isotropic 'VH' element, whose two patterns are exactly theta-hat and phi-hat). A
single-port, linearly polarised isotropic antenna with slant angle zeta has the pattern
``f(zeta) = [cos zeta, sin zeta]`` in that basis (TR 38.901 V18 7.3.2, polarization model-2,
eq. 7.3-4/7.3-5, the model Sionna RT uses by default), so the scalar path coefficient between a
transmit port ``f_t`` and a receive port ``f_r`` is (Sionna RT's field projection, real patterns)

    a = f_r^T A f_t.

Reciprocity (Lorentz; Balanis, Antenna Theory, 4th ed., Sec. 4.9): the path traced in the other
direction has the transposed matrix, ``A_ba = A_ab^T``, so a link traced from its receiver is
turned around by swapping the two port axes (:func:`veriloc_rt.propagation.raytrace.trace_links`).
"""

from __future__ import annotations

import numpy as np

from ..config import POLARIZATIONS, MaterialsConfig

#: slant angle zeta of each single-port polarization, rad (TR 38.901 7.3.2 model-2: 0 vertical,
#: pi/2 horizontal, +-pi/4 the slants of a cross-polarised pair)
SLANT_ANGLES = {"V": 0.0, "H": np.pi / 2, "+45": np.pi / 4, "-45": -np.pi / 4}
assert tuple(SLANT_ANGLES) == POLARIZATIONS

#: number of ports of the polarimetric coefficient (theta-hat, phi-hat)
NUM_POL_PORTS = 2


def port_vector(polarization: str) -> np.ndarray:
    """Pattern of a single-port isotropic antenna in the (theta-hat, phi-hat) basis.

    :param polarization: one of :data:`SLANT_ANGLES`
    :returns: [2] float64
    """
    if polarization not in SLANT_ANGLES:
        raise ValueError(f"Argument `polarization` must be one of "
                         f"{', '.join(map(repr, SLANT_ANGLES))}, not {polarization!r}")
    zeta = SLANT_ANGLES[polarization]
    return np.array([np.cos(zeta), np.sin(zeta)])


def project(a_pol: np.ndarray, rx: str, tx: str) -> np.ndarray:
    """Scalar path coefficients ``f_r^T A f_t`` for single-port antennas at both ends.

    :param a_pol: [..., 2, 2] complex, polarimetric coefficients (receive port, transmit port)
    :param rx, tx: polarizations of the receive and transmit antennas
    :returns: [...] complex128
    """
    a_pol = np.asarray(a_pol)
    if a_pol.shape[-2:] != (NUM_POL_PORTS, NUM_POL_PORTS):
        raise ValueError(f"Argument `a_pol` must end in axes (2, 2), not {a_pol.shape}")
    a = np.einsum("r,...rt,t->...", port_vector(rx), a_pol, port_vector(tx))
    return a.astype(np.complex128)


def xpd_coefficient(xpr_db: float) -> float:
    """Sionna RT's cross-polarization coefficient K_x for a cross-polarization ratio.

    Sionna's diffuse-scattering Jones matrix in the (theta-hat, phi-hat) bases of the incident and
    scattered waves is ``[[sqrt(1-K_x), -sqrt(K_x)], [sqrt(K_x), sqrt(1-K_x)]]`` (Sionna RT EM
    primer, "Scattering"; Degli-Esposti et al., IEEE TAP 55(1), 2007, eq. 11): a fraction K_x of
    the scattered power leaves in the orthogonal polarization. The ratio of co- to
    cross-polarised power is therefore XPR = (1 - K_x) / K_x, i.e. ``K_x = 1 / (1 + 10^(XPR/10))``.
    """
    return float(1.0 / (1.0 + 10.0 ** (xpr_db / 10.0)))


def apply_materials(scene, materials: MaterialsConfig) -> None:
    """Set scattering coefficient, pattern and K_x on every radio material of a Sionna scene.

    Materials that are not a ``sionna.rt.RadioMaterial`` (e.g. absorbers) have no scattering
    and are left alone.

    :param scene: a loaded ``sionna.rt.Scene``
    """
    from ..backend import import_sionna

    rt = import_sionna()
    kwargs = {"lambertian": {},
              "directive": {"alpha_r": materials.alpha_r},
              "backscattering": {"alpha_r": materials.alpha_r, "alpha_i": materials.alpha_i,
                                 "lambda_": 1.0 - materials.backscatter_fraction}}
    factory = rt.scattering_pattern_registry.get(materials.scattering_pattern)
    kx = xpd_coefficient(materials.xpr_db)
    for mat in scene.radio_materials.values():
        if not isinstance(mat, rt.RadioMaterial):
            continue
        mat.scattering_coefficient = materials.scattering_coefficient
        mat.xpd_coefficient = kx
        mat.scattering_pattern = factory(**kwargs[materials.scattering_pattern])
