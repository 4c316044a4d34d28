"""Radio materials whose edge diffraction is the Kouyoumjian-Pathak UTD (Luebbers for lossy wedges).

Sionna RT evaluates a diffracted ray's Jones matrix in ``RadioMaterial._diffraction_matrix``.
Its form, ``R0 (D1 - D4) + Rn (D2 - D3)`` in shadow-boundary bases, lets the faces' reflection
matrices multiply the incident-boundary terms D1, D2 and replaces ``Rn`` by ``-I`` whenever
``n pi > pi + phi'``. Against the exact Sommerfeld solution for a perfectly conducting half-plane
it returns the soft coefficient for both polarizations, and the result depends on which end the
rays are launched from (``docs/diffraction.md`` has the measured deviations). The materials here
keep everything else of Sionna's materials (reflection, refraction, diffuse scattering, the
frequency-dependent ITU-R P.2040 parameters) and replace only that matrix by

    E_d = -(D_s b0 b0'^T + D_h p p'^T) E_i,

the edge-fixed form of Kouyoumjian and Pathak ("A uniform geometrical theory of diffraction for
an edge in a perfectly conducting surface", Proc. IEEE 62(11), 1974, eqs. (21)-(31)), with

    p' = -(e x s') / |e x s'|,  b0' = s' x p',  p = (e x s) / |e x s|,  b0 = s x p,
    D_{s,h} = D1 + D2 + R_n^{s,h} D3 + R_0^{s,h} D4,

``e`` the edge, ``s'`` and ``s`` the incident and diffracted directions. For a perfect conductor
``R^s = -1`` and ``R^h = +1``, which is Kouyoumjian-Pathak's coefficient; for a lossy wedge the
faces' slab reflection coefficients (TE for soft, TM for hard) make it Luebbers' heuristic
(IEEE Trans. AP-32(1), 1984, eq. (6)). Luebbers evaluates ``R_0`` at the incidence angle
``phi'`` and ``R_n`` at ``n pi - phi``, which changes when source and receiver are swapped; here
each face's grazing angle is the smaller of the incident and diffracted angles to that face,
``min(phi, phi')`` and ``min(n pi - phi, n pi - phi')``, symmetric in the two ends (so the
coefficient is reciprocal) and equal to Luebbers' on the reflection boundary each term belongs
to, where that term is large. Oblique incidence enters through ``cos theta_i = sin(beta_0)
|sin psi|``.

Import this module only after :func:`veriloc_rt.backend.import_sionna` (it subclasses Sionna's
materials, which needs the Mitsuba variant selected).
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
from sionna.rt import ITURadioMaterial, RadioMaterial
from sionna.rt.utils import (cot_times_f_utd, implicit_basis_vector,
                             itu_coefficients_single_layer_slab, jones_matrix_from_real_imag,
                             wedge_interior_angle)

__all__ = ["UTDITURadioMaterial", "UTDRadioMaterial", "use_utd_materials", "DIFFRACTION_MODELS"]

#: ``propagation.raytrace.diffraction_coefficient`` values
DIFFRACTION_MODELS = ("utd", "sionna")


def _face_angle(k_proj: mi.Vector3f, t0: mi.Vector3f, n0: mi.Vector3f) -> mi.Float:
    """Angle in [0, 2 pi) of the in-plane direction ``k_proj`` from the 0-face, towards n0."""
    ang = dr.safe_acos(dr.dot(k_proj, t0))
    return dr.select(dr.dot(k_proj, n0) >= 0, ang, dr.two_pi - ang)


def _utd_diffraction_matrix(self, to_world: mi.Matrix3f, ki_local: mi.Vector3f,
                            ko_local: mi.Vector3f, si: mi.SurfaceInteraction3f,
                            eta: mi.Complex2f, wavenumber: mi.Float) -> mi.Matrix4f:
    """The Kouyoumjian-Pathak / Luebbers diffraction Jones matrix (module docstring), in
    place of ``RadioMaterial._diffraction_matrix`` (same signature)."""
    # Local frame: z is the 0-face normal; Sionna stores the edge in si.dn_du and the
    # n-face normal in si.dn_dv, oriented so that n0 x e points into the 0-face.
    e = si.dn_du
    nn = si.dn_dv
    n0 = mi.Vector3f(0, 0, 1)
    t0 = dr.normalize(dr.cross(n0, e))
    n = (dr.two_pi - wedge_interior_angle(n0, nn)) / dr.pi

    sin_beta0 = dr.safe_sqrt(1. - dr.square(dr.dot(ki_local, e)))
    ki_proj = dr.normalize(ki_local - dr.dot(ki_local, e) * e)
    ko_proj = dr.normalize(ko_local - dr.dot(ko_local, e) * e)
    phi_p = _face_angle(-ki_proj, t0, n0)     # towards the source
    phi = _face_angle(ko_proj, t0, n0)        # towards the receiver

    # distance parameter for spherical-wave incidence (KP eq. (27)); dp_du holds s, s'
    s, s_p = si.dp_du.x, si.dp_du.y
    kl = wavenumber * s * s_p * dr.rcp(s + s_p) * dr.square(sin_beta0)

    def a_pm(beta, sign):
        big_n = dr.round((beta + sign * dr.pi) / (2 * n * dr.pi))
        return 2 * dr.square(dr.cos((2 * n * dr.pi * big_n - beta) / 2))

    factor = -dr.exp(mi.Complex2f(0, -dr.pi / 4)) * dr.rcp(
        2 * n * dr.safe_sqrt(dr.two_pi * wavenumber) * sin_beta0)
    dm, dp = phi - phi_p, phi + phi_p
    d1 = factor * cot_times_f_utd((dr.pi + dm) / (2 * n), kl * a_pm(dm, 1.), n, kl)
    d2 = factor * cot_times_f_utd((dr.pi - dm) / (2 * n), kl * a_pm(dm, -1.), n, kl)
    d3 = factor * cot_times_f_utd((dr.pi + dp) / (2 * n), kl * a_pm(dp, 1.), n, kl)
    d4 = factor * cot_times_f_utd((dr.pi - dp) / (2 * n), kl * a_pm(dp, -1.), n, kl)

    # face reflection coefficients at the reciprocal grazing angles (module docstring),
    # reduced by sqrt(1 - S^2) as Sionna's specular reflection is
    wavelength = dr.two_pi / wavenumber
    psi_0 = dr.minimum(phi, phi_p)
    psi_n = n * dr.pi - dr.maximum(phi, phi_p)
    r_te_0, r_tm_0, _, _ = itu_coefficients_single_layer_slab(
        sin_beta0 * dr.abs(dr.sin(psi_0)), eta, self._d, wavelength)
    r_te_n, r_tm_n, _, _ = itu_coefficients_single_layer_slab(
        sin_beta0 * dr.abs(dr.sin(psi_n)), eta, self._d, wavelength)
    rough = dr.sqrt(1. - dr.square(self._s))
    d12 = d1 + d2
    d_s = d12 + rough * (r_te_n * d3 + r_te_0 * d4)
    d_h = d12 + rough * (r_tm_n * d3 + r_tm_0 * d4)

    # edge-fixed ray bases (KP eqs. (21)-(22)) and Sionna's implicit bases of both rays
    p_in = -dr.normalize(dr.cross(e, ki_local))
    b_in = dr.cross(ki_local, p_in)
    p_out = dr.normalize(dr.cross(e, ko_local))
    b_out = dr.cross(ko_local, p_out)
    th_in = to_world.T @ implicit_basis_vector(to_world @ ki_local)
    th_out = to_world.T @ implicit_basis_vector(to_world @ ko_local)
    bases_in = (th_in, dr.cross(ki_local, th_in))
    bases_out = (th_out, dr.cross(ko_local, th_out))
    m_s = mi.Matrix2f([[dr.dot(o, b_out) * dr.dot(b_in, i) for i in bases_in] for o in bases_out])
    m_h = mi.Matrix2f([[dr.dot(o, p_out) * dr.dot(p_in, i) for i in bases_in] for o in bases_out])
    real = -(d_s.real * m_s + d_h.real * m_h)
    imag = -(d_s.imag * m_s + d_h.imag * m_h)
    return jones_matrix_from_real_imag(real, imag)


# (nanobind classes take one base: the method is shared by assignment, not by a mixin)
class UTDITURadioMaterial(ITURadioMaterial):
    """Sionna's ITU-R P.2040 material with the UTD diffraction coefficient."""

    _diffraction_matrix = _utd_diffraction_matrix


class UTDRadioMaterial(RadioMaterial):
    """Sionna's generic radio material with the UTD diffraction coefficient."""

    _diffraction_matrix = _utd_diffraction_matrix


_UTD_MATERIALS = (UTDITURadioMaterial, UTDRadioMaterial)


def _replacement(mat) -> RadioMaterial | None:
    name = f"utd-{mat.name}"
    common = dict(thickness=mat.thickness, scattering_coefficient=mat.scattering_coefficient,
                  xpd_coefficient=mat.xpd_coefficient, color=mat.color)
    if isinstance(mat, ITURadioMaterial):
        twin = UTDITURadioMaterial(name=name, itu_type=mat.itu_type, **common)
    elif isinstance(mat, RadioMaterial):
        twin = UTDRadioMaterial(name=name, relative_permittivity=mat.relative_permittivity,
                                conductivity=mat.conductivity,
                                frequency_update_callback=mat.frequency_update_callback, **common)
    else:
        return None     # e.g. Sionna's absorber: no diffraction to replace
    twin.scattering_pattern = mat.scattering_pattern
    return twin


def use_utd_materials(scene) -> int:
    """Give every object of ``scene`` a UTD twin of its radio material; returns how many
    materials were replaced. Call after loading the scene and before setting its frequency
    (the twins update their ITU parameters with the frequency as Sionna's do)."""
    twins: dict[str, RadioMaterial] = {}
    for obj in scene.objects.values():
        mat = obj.radio_material
        if isinstance(mat, _UTD_MATERIALS):
            continue
        if mat.name not in twins:
            twin = _replacement(mat)
            if twin is None:
                continue
            twins[mat.name] = twin
        obj.radio_material = twins[mat.name]
    return len(twins)
